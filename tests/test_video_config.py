"""The tracker's rules in one place (issue 67; lfsam.video.tracking.config): one frozen
dataclass whose defaults are the constants the tracker reads, each rule switched off from it
for a ``with`` block, the constants restored after."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from lfsam.video.tracking import contest, rules
from lfsam.video.tracking.config import SOURCES, TrackerConfig, switches
from test_video_search_unanswered import _tracked


def test_the_defaults_are_the_constants_the_tracker_reads():
    assert TrackerConfig() == TrackerConfig.current()
    assert set(SOURCES) == {f.name for f in dataclasses.fields(TrackerConfig)}
    for name, (module, const) in SOURCES.items():
        field = TrackerConfig.__dataclass_fields__[name]
        assert field.type in ("bool", "int", "float"), name
        assert type(getattr(TrackerConfig(), name)).__name__ == field.type, (name, module, const)


def test_every_switch_is_a_boolean_rule_and_an_unknown_name_is_refused():
    assert "depth_gate" in switches() and "contest_check" in switches()
    assert "max_growth" not in switches()
    with pytest.raises(ValueError, match="not a rule's switch: max_growth"):
        TrackerConfig().without("max_growth")
    with pytest.raises(dataclasses.FrozenInstanceError):
        TrackerConfig().depth_gate = False  # type: ignore[misc]


def test_applied_sets_the_rules_for_the_block_and_restores_them_after_an_error():
    config = TrackerConfig(held=0.25).without("depth_gate", "contest_check")
    with pytest.raises(RuntimeError), config.applied():
        assert (rules.DEPTH_GATE, contest.CHECK, rules.HELD) == (False, False, 0.25)
        assert TrackerConfig.current() == config
        raise RuntimeError
    assert (rules.DEPTH_GATE, contest.CHECK, rules.HELD) == (True, True, 0.5)
    assert TrackerConfig.current() == TrackerConfig()


def test_a_rule_switched_off_from_the_config_is_off_in_the_search():
    """tests/test_video_search_unanswered.py's case: the object clicked behind another is found
    where it comes out with the retry, waits for good without it, and is found again after."""
    def states():
        return [r.meta["tracks"]["2"] for _, r in _tracked()]

    with TrackerConfig().without("retry_unanswered").applied():
        assert states() == ["hidden", "waiting", "waiting"]
    assert states() == ["hidden", "found", "tracked"]


def test_two_threads_applying_configurations_take_turns():
    """Each thread sees its own configuration for its whole block (issue 67: ``applied`` was not
    thread-safe): the second thread's block waits until the first has restored the rules."""
    import threading

    seen: dict[str, list[bool]] = {"off": [], "on": []}
    inside = threading.Event()

    def first():
        with TrackerConfig().without("depth_gate").applied():
            inside.set()
            for _ in range(50):
                seen["off"].append(rules.DEPTH_GATE)
                threading.Event().wait(0.001)

    def second():
        inside.wait()
        with TrackerConfig().applied():
            seen["on"].append(rules.DEPTH_GATE)

    threads = [threading.Thread(target=first), threading.Thread(target=second)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert seen == {"off": [False] * 50, "on": [True]}
    assert rules.DEPTH_GATE is True


def test_the_design_notes_table_lists_every_rule_with_its_default():
    """docs/design.md section 10, "The tracker's rules": one row per field, its default and
    constant as in the dataclass (the descriptions live in the field docstrings)."""
    text = (Path(__file__).resolve().parents[1] / "docs" / "design.md").read_text()
    section = text[text.index("### The tracker's rules"):]
    section = section[:section.index("\n#", 1)]
    rows = {}
    for line in section.splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|", 3)]
        if len(cells) == 4 and cells[0].startswith("`"):
            rows[cells[0].strip("`")] = (cells[1].strip("`"), cells[2].strip("`"), cells[3])
    assert set(rows) == set(SOURCES)
    defaults, described = TrackerConfig(), _field_docs()
    for name, (module, const) in SOURCES.items():
        assert rows[name] == (repr(getattr(defaults, name)), f"{module}.{const}",
                              described[name]), name


def _field_docs() -> dict[str, str]:
    """Each field's docstring as the design notes write it: one line, without its "Default"
    sentence, Sphinx roles dropped."""
    import ast
    import re

    from lfsam.video.tracking import config

    tree = ast.parse(Path(config.__file__).read_text())
    (cls,) = [n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "TrackerConfig"]
    out = {}
    for node, after in zip(cls.body, cls.body[1:], strict=False):
        if isinstance(node, ast.AnnAssign) and isinstance(after, ast.Expr):
            text = " ".join(after.value.value.split())
            text = re.sub(r"\s*Default ``.*?`` \(``.*?``\)\.$", "", text).replace("``", "`")
            out[node.target.id] = re.sub(r":(data|func|attr|mod):`~?", "`", text)
    return out
