"""The dock's controls: the boxes, buttons, object list, progress bar and status line, laid out.

Built here and only here; the dock widget (:mod:`lfsam.viewer.widget`) connects them to its
actions and reads them (docs/design.md section 8). Besides the layout, this module owns what the
boxes mean: which weights the "Weights" box names (the model hub's, untrained ones or a
checkpoint file), the "file…" item that asks for a file, the object list's rows, and the dialogs
that ask for a file or an export format.
"""

from __future__ import annotations

from collections.abc import Container, Iterable, Sequence

from qtpy.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QGridLayout,
    QHBoxLayout,
    QInputDialog,
    QLabel,
    QLineEdit,
    QListWidget,
    QListWidgetItem,
    QProgressBar,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

__all__ = [
    "FILE_ITEM",
    "FOLDER_ITEM",
    "HUB_WEIGHTS",
    "RANDOM_WEIGHTS",
    "DockControls",
    "ask_export",
    "ask_open_file",
    "ask_open_folder",
    "ask_save_file",
    "item_id",
]

#: The last item of the disparity box and the weights box's second last: asks for a file.
FILE_ITEM = "file…"
#: The weights box's last item: asks for a transformers-format model folder (docs/design.md
#: section 3.8; EdgeTAM or SAM 2 with config.json + *.safetensors).
FOLDER_ITEM = "folder…"
#: The weights box: the model hub's trained weights (cached), untrained ones, a .pt file or a
#: transformers-format folder.
HUB_WEIGHTS = "trained (hub cache)"
RANDOM_WEIGHTS = "random (tests only)"

_USER_ROLE = 256  # Qt.UserRole: the object id behind a row of the object list


def _choose_item(box: QComboBox, text: str, trailing: int = 1) -> None:
    """Select ``text`` in ``box``, inserting it before the ``trailing`` last items ("file…",
    "folder…") if it is new."""
    if box.findText(text) < 0:
        box.insertItem(box.count() - trailing, text)
    box.setCurrentText(text)


class DockControls:
    """The dock's Qt widgets and their layout (:attr:`layout`); nothing is connected here.

    Parameters
    ----------
    models : sequence of str
        The model box's items.
    model : str
        The model chosen.
    disparity_sources : sequence of str
        The disparity box's items before "file…".
    disparity : str, optional
        The disparity source chosen (a path is added as an item); default the first source.
    reference_modes : sequence of str
        The "Everything from" box's items.
    checkpoint : str, optional
        A checkpoint file chosen in the weights box.
    random_weights : bool
        Untrained weights chosen (when there is no checkpoint).
    refine_views : str or int
        The "Refine views" box's choice (docs/design.md section 3.7): ``all``, ``sparse`` or N.
    consensus : bool
        The "Consensus" box's state: the multi-view consensus (docs/design.md section 3.9).
    """

    def __init__(
        self,
        *,
        models: Sequence[str],
        model: str,
        disparity_sources: Sequence[str],
        disparity: str | None = None,
        reference_modes: Sequence[str],
        checkpoint: str | None = None,
        random_weights: bool = False,
        refine_views: str | int = "all",
        consensus: bool = False,
    ) -> None:
        self.model_box = QComboBox()
        self.model_box.addItems(list(models))
        self.model_box.setCurrentText(model)
        self.weights_box = QComboBox()
        self.weights_box.addItems([HUB_WEIGHTS, RANDOM_WEIGHTS, FILE_ITEM, FOLDER_ITEM])
        self.weights_box.setToolTip(
            "SAM 2 weights: the model hub's (downloaded once into the cache), untrained ones "
            "of the same architecture, a checkpoint file (Meta's .pt) of the chosen model, or "
            "a transformers-format folder (EdgeTAM, SAM 2: config.json + *.safetensors; choose "
            "the model 'transformers' to take whatever it holds)"
        )
        self.show_weights(checkpoint, random_weights)
        self.disparity_box = QComboBox()
        self.disparity_box.addItems([*disparity_sources, FILE_ITEM])
        if disparity is not None:
            _choose_item(self.disparity_box, disparity)
        self.references_box = QComboBox()
        self.references_box.addItems(list(reference_modes))
        self.references_box.setToolTip(
            "Segment everything from the center view (the paper's setting), or also from the "
            "corner views, the outer ring or every view, to find objects the center cannot see"
        )
        self.refine_box = QComboBox()
        self.refine_box.addItems(["all", "sparse"])
        _choose_item(self.refine_box, str(refine_views))
        self.refine_box.setToolTip(
            "Views SAM 2 refines: all (the paper) or sparse (about one in six, spread over the "
            "grid; the others take the masks of the refined views nearest to them). Choosing "
            "all after a sparse pass refines the remaining views"
        )
        #: The multi-view consensus (docs/design.md section 3.9); its ``clicked`` signal is the
        #: user's toggle (:meth:`show_consensus` sets it silently).
        self.consensus_box = QCheckBox()
        self.consensus_box.setChecked(bool(consensus))
        self.consensus_box.setToolTip(
            "Multi-view consensus: after refinement, each view's mask of each object is voted "
            "with the masks of its nearest views, carried by disparity, so one view's wrong "
            "answer is outvoted by its neighbours' (costs more: about twice the work of a "
            "sparse fill). Toggling it refines the objects again"
        )
        self.load_button = QPushButton("Load model")
        self.polarity_label = QLabel()
        self.show_polarity(False)
        self.segment_button = QPushButton("Segment [S]")
        self.commit_button = QPushButton("Commit [C]")
        self.clear_button = QPushButton("Clear [Shift-C]")
        self.undo_button = QPushButton("Undo [Ctrl-Z]")
        self.redo_button = QPushButton("Redo [Ctrl-Shift-Z]")
        self.toggle_button = QPushButton("Toggle +/- [T]")
        self.everything_button = QPushButton("Segment everything")
        #: Text prompts (docs/design.md section 9): a phrase, found in the view shown.
        self.find_edit = QLineEdit()
        self.find_edit.setPlaceholderText("find a phrase, e.g. red cup")
        self.find_edit.setToolTip(
            "Every instance of the phrase in the view shown becomes an object (SAM 3's concept "
            "detector; with the oracle model, the scene's ground-truth categories)"
        )
        self.find_button = QPushButton("Find")
        self.objects = QListWidget()
        self.edit_button = QPushButton("Edit selected")
        self.remove_button = QPushButton("Remove selected")
        self.open_labels_button = QPushButton("Reopen selected labels layer")
        #: One button per display, keyed by :data:`lfsam.viewer.layers.ORDERS`'s names.
        self.view_buttons = {
            "views": QPushButton("Views"),
            "epi-row": QPushButton("EPI (row)"),
            "epi-column": QPushButton("EPI (column)"),
        }
        #: Light-field videos only (docs/design.md section 10); hidden for a single light field.
        self.track_button = QPushButton("Track through the video [Ctrl-T]")
        self.track_button.setToolTip(
            "Track every object from its clicks (on any frame) through all frames; each "
            "frame's labels show as it finishes"
        )
        self.track_button.setVisible(False)
        self.stop_track_button = QPushButton("Stop tracking")
        self.stop_track_button.setToolTip(
            "Stop the track after the frame being tracked; nothing of the stopped track is "
            "saved (the previous track, if any, is shown again)"
        )
        self.stop_track_button.setVisible(False)
        self.stop_track_button.setEnabled(False)
        #: A live stream (docs/design.md section 10): a frames folder a camera is writing.
        self.follow_button = QPushButton("Follow a frames folder…")
        self.follow_button.setToolTip(
            "Segment a light-field camera's frames as they land in a folder (renamed in when "
            "complete; a file named END ends the stream): the latest frame and its masks are "
            "shown, a click starts a new object from the next frame on"
        )
        self.latest_box = QCheckBox("Newest frame only")
        self.latest_box.setToolTip(
            "Never fall behind the camera (--latest): always segment the newest frame that has "
            "landed and skip the older ones not yet started (listed in the result)")
        #: Follow in automatic mode: every object of the first frame found and tracked.
        self.follow_auto_box = QCheckBox("Follow: everything in the first frame")
        self.follow_auto_box.setToolTip(
            "Following a stream, find every object of its first frame automatically (as "
            "\"Segment everything\") and track them; clicks add more objects")
        self.stop_follow_button = QPushButton("Stop following")
        self.stop_follow_button.setToolTip("End the stream after the frame being segmented; "
                                           "the result folder keeps every frame done")
        self.stop_follow_button.setEnabled(False)
        self.save_button = QPushButton("Save result…")
        self.export_button = QPushButton("Export…")
        self.progress = QProgressBar()
        self.progress.setRange(0, 1)
        self.progress.setValue(0)
        self.status = QLabel("")
        self.status.setWordWrap(True)
        self.layout = self._lay_out()

    def show_refine_views(self, setting: str | int) -> None:
        """Show ``setting`` in the "Refine views" box (an N is added as an item)."""
        _choose_item(self.refine_box, str(setting))

    @property
    def consensus(self) -> bool:
        """Whether the "Consensus" box is checked (docs/design.md section 3.9)."""
        return self.consensus_box.isChecked()

    def show_consensus(self, on: bool) -> None:
        """Check or uncheck the "Consensus" box (no ``clicked`` signal)."""
        self.consensus_box.setChecked(bool(on))

    def _lay_out(self) -> QVBoxLayout:
        form = QFormLayout()
        form.addRow("Model", self.model_box)
        form.addRow("Weights", self.weights_box)
        form.addRow("Disparity", self.disparity_box)
        form.addRow("Everything from", self.references_box)
        form.addRow("Refine views", self.refine_box)
        form.addRow("Consensus", self.consensus_box)
        grid = QGridLayout()
        prompt_buttons = [
            self.segment_button, self.commit_button, self.toggle_button, self.clear_button,
            self.undo_button, self.redo_button,
        ]
        for i, button in enumerate(prompt_buttons):
            grid.addWidget(button, i // 2, i % 2)
        layout = QVBoxLayout()
        layout.addLayout(form)
        layout.addWidget(self.load_button)
        layout.addWidget(self.polarity_label)
        layout.addLayout(grid)
        layout.addWidget(self.everything_button)
        layout.addLayout(_row([self.find_edit, self.find_button]))
        layout.addWidget(QLabel("Objects (double-click to edit)"))
        layout.addWidget(self.objects)
        layout.addLayout(_row([self.edit_button, self.remove_button]))
        layout.addWidget(self.open_labels_button)
        layout.addLayout(_row(self.view_buttons.values()))
        layout.addLayout(_row([self.track_button, self.stop_track_button]))
        layout.addLayout(_row([self.follow_button, self.stop_follow_button]))
        layout.addWidget(self.latest_box)  # a line each: the dock stays narrow (issue 46)
        layout.addWidget(self.follow_auto_box)
        layout.addLayout(_row([self.save_button, self.export_button]))
        layout.addWidget(self.progress)
        layout.addWidget(self.status)
        layout.addStretch(1)
        return layout

    # --- what the boxes say -------------------------------------------------------------------
    def show_weights(self, checkpoint: str | None, random_weights: bool) -> None:
        """Select a checkpoint file (added as an item), the untrained or the hub's weights."""
        if checkpoint:
            _choose_item(self.weights_box, str(checkpoint), trailing=2)
        else:
            self.weights_box.setCurrentText(RANDOM_WEIGHTS if random_weights else HUB_WEIGHTS)

    def chosen_weights(self) -> tuple[str | None, bool]:
        """The weights box's choice as ``(checkpoint, random_weights)`` (not on "file…")."""
        text = self.weights_box.currentText()
        if text in (HUB_WEIGHTS, RANDOM_WEIGHTS):
            return None, text == RANDOM_WEIGHTS
        return text, False

    def pick_weights(
        self, parent: QWidget, in_use: tuple[str | None, bool]
    ) -> tuple[str | None, bool] | None:
        """The weights chosen, ``(checkpoint, random_weights)``; on "file…" (a .pt file) or
        "folder…" (a transformers-format folder) a dialog asks for the checkpoint. None when it
        is cancelled (the weights ``in_use`` are shown again)."""
        choice = self.weights_box.currentText()
        if choice in (FILE_ITEM, FOLDER_ITEM):
            path = (ask_open_file(parent, "SAM 2 checkpoint (.pt)", "*.pt *.pth")
                    if choice == FILE_ITEM
                    else ask_open_folder(parent, "Transformers model folder (config.json)"))
            self.show_weights(*((path, False) if path else in_use))
            if path is None:
                return None
        return self.chosen_weights()

    def pick_disparity(self, parent: QWidget, in_use: str | None) -> str | None:
        """The disparity source chosen; on "file…" a dialog asks for a ``.npy`` file. None when
        it is cancelled (the source ``in_use``, if any, is shown again)."""
        if self.disparity_box.currentText() == FILE_ITEM:
            path = ask_open_file(parent, "Disparity (.npy)", "*.npy")
            if path is None:
                if in_use is not None:
                    _choose_item(self.disparity_box, in_use)
                return None
            _choose_item(self.disparity_box, path)
        return self.disparity_box.currentText()

    def show_polarity(self, negative: bool) -> None:
        """Say which points plain clicks add."""
        text = "negative" if negative else "positive"
        self.polarity_label.setText(f"Clicks add {text} points (Ctrl-click: the other; T)")

    def show_objects(self, ids: Iterable[int], current: int, auto: Container[int]) -> None:
        """List the objects ``ids``: the ``current`` one (being edited), the automatic ones
        (``auto``) and the committed ones (the others)."""
        self.objects.clear()
        for obj_id in ids:
            role = "editing" if obj_id == current else "automatic" if obj_id in auto else (
                "committed"
            )
            item = QListWidgetItem(f"{obj_id}  ({role})")
            item.setData(_USER_ROLE, obj_id)
            self.objects.addItem(item)

    def selected_id(self) -> int | None:
        """The id of the object selected in the list, or None."""
        return item_id(self.objects.currentItem())


def item_id(item: QListWidgetItem | None) -> int | None:
    """The object id behind a row of the object list (None for no row)."""
    return None if item is None else int(item.data(_USER_ROLE))


def _row(widgets: Iterable[QWidget]) -> QHBoxLayout:
    row = QHBoxLayout()
    for widget in widgets:
        row.addWidget(widget)
    return row


# --- dialogs ----------------------------------------------------------------------------------
def ask_open_file(parent: QWidget, title: str, pattern: str) -> str | None:
    """Ask for an existing file; None when cancelled."""
    path, _ = QFileDialog.getOpenFileName(parent, title, "", pattern)
    return path or None


def ask_open_folder(parent: QWidget, title: str) -> str | None:
    """Ask for an existing folder; None when cancelled."""
    path = QFileDialog.getExistingDirectory(parent, title, "")
    return path or None


def ask_save_file(parent: QWidget, title: str, default: str, pattern: str = "") -> str | None:
    """Ask for a new file or folder name; None when cancelled."""
    path, _ = QFileDialog.getSaveFileName(parent, title, default, pattern)
    return path or None


def ask_export(parent: QWidget, formats: Sequence[str]) -> tuple[str, str] | None:
    """Ask for an export format, then a new folder; ``(folder, format)`` or None (cancelled)."""
    to, ok = QInputDialog.getItem(parent, "Export", "Format", list(formats), 0, False)
    if not ok:
        return None
    out = ask_save_file(parent, "Export to a new folder", "export")
    return None if out is None else (out, to)
