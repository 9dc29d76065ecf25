"""The check both live fronts share (issue 47): each frame's line names the objects the result's
states (``meta["tracks"]``) give as hidden there, since the first frame of their run, and the
end line names every object hidden at some frame (tests/test_video_follow.py for ``lfsam
segment --follow``, tests/test_viewer_follow.py for the viewer's Follow)."""

from __future__ import annotations


def check_hidden_lines(lines: list[str], names: list[str], tracks: dict[str, list[str]],
                       ended: str) -> dict[int, list[int]]:
    """Assert the lines against ``tracks``; return the hidden ids per frame."""
    hidden = {f: [int(i) for i, states in tracks.items() if states[f] == "hidden"]
              for f in range(len(names))}
    for f, ids in hidden.items():
        line = next(x for x in lines if x.startswith(f"frame {f} ({names[f]}): "))
        assert ("searching for" in line) == bool(ids), line
        for i in ids:
            since = min(g for g in range(f + 1)
                        if all(tracks[str(i)][h] == "hidden" for h in range(g, f + 1)))
            assert f"{i} (hidden since frame {since})" in line, line
    end = next(x for x in lines if x.startswith(ended))
    assert all(f"object {i} in frame(s) " in end for ids in hidden.values() for i in ids), end
    return hidden
