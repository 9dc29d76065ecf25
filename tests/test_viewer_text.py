"""The viewer's "Find" field (issue 26): a phrase typed in the dock adds every instance in the
view shown as an object, computed in the worker thread (docs/design.md section 9). The oracle
answers from the scene's ground-truth categories, so the objects are checked exactly. Needs a
display: ``make test`` runs pytest under ``xvfb-run``."""

from __future__ import annotations

import numpy as np
import pytest

from lfsam.segmenters.text import phrase_matches
from lfsam.synth import generate_scene
from lfsam.viewer import layers as L
from lfsam.viewer.widget import LightFieldWidget

TIMEOUT = 60_000
VIEW = (0, 2)


@pytest.fixture(scope="module")
def scene():
    return generate_scene(grid=(3, 3), size=(48, 64), seed=3, num_objects=5,
                          label_background=False)


def test_find_field_adds_every_instance_in_the_view_shown(make_napari_viewer, qtbot, scene):
    viewer = make_napari_viewer()
    widget = LightFieldWidget(viewer, lightfield=scene, model="oracle", disparity="gt")
    viewer.window.add_dock_widget(widget)
    qtbot.waitUntil(lambda: widget.session.loaded and not widget.busy, timeout=TIMEOUT)
    stars = {i for i, name in scene.categories.items() if phrase_matches("star", name)}
    expected = stars & set(np.unique(scene.labels[VIEW]).tolist())
    assert expected  # the scene has stars in that view

    viewer.dims.current_step = (*VIEW, *viewer.dims.current_step[2:])
    widget.controls.find_edit.setText("star")
    qtbot.keyClick(widget.controls.find_edit, "\r")  # Enter in the field, as a user would
    qtbot.waitUntil(lambda: not widget.busy and bool(widget.session.object_ids), timeout=TIMEOUT)

    ids = widget.session.object_ids
    assert len(ids) == len(expected)
    assert "find 'star'" in widget.status.text() and "view 0,2" in widget.status.text()
    assert all(widget.session.predictor.category(i) == "star" for i in ids)
    found = widget.layers[L.AUTO].data  # found objects are shown with the automatic ones
    for obj_id in ids:  # each object is one star, in every view
        label = np.bincount(scene.labels[VIEW][found[VIEW] == obj_id]).argmax()
        assert label in expected
        for s in range(3):
            for t in range(3):
                truth = scene.labels[s, t] == label
                mine = found[s, t] == obj_id
                assert np.count_nonzero(mine & truth) >= 0.9 * np.count_nonzero(mine | truth)
    assert widget.objects.count() >= len(ids)

    # a phrase with no instance: a clear status, nothing added
    widget.find("cat")
    qtbot.waitUntil(lambda: not widget.busy and "cat" in widget.status.text(), timeout=TIMEOUT)
    assert "no object(s)" in widget.status.text()
    assert widget.session.object_ids == ids
