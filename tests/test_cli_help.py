"""`lfsam --help` and every subcommand's --help teach with an example invocation."""

from __future__ import annotations

import pytest

from lfsam.cli.main import SUBCOMMANDS, build_parser, main


def test_every_listed_subcommand_exists():
    parser = build_parser()
    choices = next(a for a in parser._actions if a.dest == "command").choices
    assert sorted(choices) == sorted(SUBCOMMANDS)


@pytest.mark.parametrize("command", SUBCOMMANDS)
def test_help_has_an_example(command, capsys):
    with pytest.raises(SystemExit) as exit_info:
        main([command, "--help"])
    assert exit_info.value.code == 0
    text = capsys.readouterr().out
    assert "examples:" in text
    assert f"  lfsam {command} " in text


def test_top_level_help_lists_commands_and_examples(capsys):
    with pytest.raises(SystemExit):
        main(["--help"])
    text = capsys.readouterr().out
    assert "examples:" in text and all(name in text for name in SUBCOMMANDS)
