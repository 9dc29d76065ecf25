"""Rendering around objects with view-consistent masks (issue 66; docs/design.md section 13).

Plain NumPy arrays in and out, torch inside (any device):

- :func:`refocus` — shift-and-add at one disparity (Ng 2005);
- :func:`see_through` — synthetic-aperture see-through that leaves out every ray hitting the
  chosen objects, with the share of views that saw each pixel (Vaish et al. 2004, 2006);
- :func:`remove_objects` — a whole light field without the objects, filled from the views that
  see what lies behind them, the rest inpainted by OpenCV and flagged (Jarabo et al. 2014);
- :func:`object_focus`, :func:`behind_focus` — the disparity of an object / of what lies behind it;
- :func:`objects_in_front` — the other objects in front of a focal plane (see-through leaves
  them out).
"""

from lfsam.render.refocus import object_focus, refocus
from lfsam.render.remove import remove_objects
from lfsam.render.see_through import behind_focus, objects_in_front, see_through

__all__ = [
    "behind_focus", "object_focus", "objects_in_front", "refocus", "remove_objects", "see_through",
]
