"""Command-line prompts: ``--point``/``--neg``/``--box`` with optional ``@S,T`` view tags and
``#F`` frame tags (a light-field video's 0-based frame, default 0; docs/design.md section 10).

docs/design.md section 8: ``X,Y@S,T`` is a click at pixel column ``X``, row ``Y`` of view
``(S, T)``; no tag means the center view. Each ``--point`` or ``--box`` starts a new object and a
``--neg`` belongs to the object started last, so the options' order matters: they are collected
in order by :class:`PromptAction`.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from lfsam.errors import LfsamError
from lfsam.prompts import BoxPrompt, ObjectPrompts, PointPrompt

__all__ = ["PROMPT_PARSERS", "PromptAction", "objects_from_items", "parse_tagged"]


def parse_tagged(text: str, count: int) -> tuple[tuple[float, ...], tuple[int, int] | None]:
    """``"X,Y"`` or ``"X,Y@S,T"`` (``count`` numbers before the ``@``).

    Raises
    ------
    argparse.ArgumentTypeError
        One line naming what was expected (argparse prints it as a usage error).
    """
    body, _, tag = text.partition("@")
    try:
        values = tuple(float(x) for x in body.split(","))
    except ValueError:
        values = ()
    if len(values) != count:
        names = "X,Y" if count == 2 else "X0,Y0,X1,Y1"
        raise argparse.ArgumentTypeError(
            f"expected {names} or {names}@S,T ({count} comma-separated numbers), got {text!r}"
        )
    view = None
    if tag:
        try:
            s, t = (int(x) for x in tag.split(","))
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"the view after @ must be S,T (two whole numbers: view row, view column), "
                f"got {tag!r}"
            ) from None
        view = (s, t)
    return values, view


def parse_frame_tag(text: str) -> tuple[str, int | None]:
    """Split ``"...#F"`` into the rest and the frame ``F`` (None without ``#``).

    Raises
    ------
    argparse.ArgumentTypeError
        If ``F`` is not a whole number >= 0.
    """
    body, hash_, tag = text.partition("#")
    if not hash_:
        return text, None
    if not tag.isdigit():
        raise argparse.ArgumentTypeError(
            f"the frame after # must be a whole number >= 0 (0-based frame), got {tag!r}"
        )
    return body, int(tag)


def _item(kind: str, text: str, count: int) -> tuple:
    body, frame = parse_frame_tag(text)
    return (kind, *parse_tagged(body, count), frame)


PROMPT_PARSERS = {
    "point": lambda text: _item("point", text, 2),
    "neg": lambda text: _item("neg", text, 2),
    "box": lambda text: _item("box", text, 4),
}


class PromptAction(argparse.Action):
    """Append ``(kind, values, view)`` to one shared list, keeping the options' order."""

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: Any,
        option_string: str | None = None,
    ) -> None:
        items = list(getattr(namespace, self.dest, None) or [])
        items.append(values)
        setattr(namespace, self.dest, items)


def objects_from_items(items: Sequence[tuple], first_id: int = 1) -> list[ObjectPrompts]:
    """Objects from the ordered ``(kind, values, view[, frame])`` items of
    :class:`PromptAction`.

    Raises
    ------
    LfsamError
        A ``--neg`` before any ``--point`` or ``--box``.
    """
    objects: list[ObjectPrompts] = []
    for kind, values, view, *rest in items:
        frame = rest[0] if rest else None
        if kind == "point":
            point = PointPrompt(*values, True, view, frame)
            objects.append(ObjectPrompts(first_id + len(objects), (point,)))
        elif kind == "box":
            box = BoxPrompt(*values, view=view, frame=frame)
            objects.append(ObjectPrompts(first_id + len(objects), (), box))
        else:
            if not objects:
                raise LfsamError(
                    "--neg X,Y belongs to the object started by the last --point or --box; "
                    "give a --point or --box before it"
                )
            objects[-1] = objects[-1].with_points([PointPrompt(*values, False, view, frame)])
    return objects
