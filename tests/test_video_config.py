"""The tracker's rules in one place (issue 67; lfsam.video.tracking.config): one frozen
dataclass whose defaults are the constants the tracker reads, each rule switched off from it
for a ``with`` block, the constants restored after."""

from __future__ import annotations

import dataclasses

import pytest

from lfsam.video.tracking import contest, rules
from lfsam.video.tracking.config import SOURCES, TrackerConfig, switches
from test_video_search_core import _search


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
    """tests/test_video_search_core.py's case: found with the interior rule, hidden without."""
    assert _search(66) is not None
    with TrackerConfig().without("core_support").applied():
        assert _search(66) is None
    assert _search(66) is not None
