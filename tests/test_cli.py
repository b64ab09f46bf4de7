from feeder.cli import main


def test_every_cli_command_has_a_main():
    """Each `feeder <command>` maps to an importable module with a main(argv)."""
    import importlib

    from feeder.cli import COMMANDS

    for name, (module, _) in COMMANDS.items():
        assert callable(getattr(importlib.import_module(module), "main", None)), name


def test_unknown_command_exits_2(capsys):
    assert main(["no-such-command"]) == 2
    assert "unknown command" in capsys.readouterr().err


def test_help_lists_every_command_with_its_description(capsys):
    from feeder.cli import COMMANDS

    assert main(["--help"]) == 0
    lines = capsys.readouterr().out.splitlines()
    for name, (_, help_) in COMMANDS.items():
        assert any(line.split()[:1] == [name] and line.rstrip().endswith(help_) for line in lines), name


# ---------------------------------------------------------------- help texts (issue 36, item 5)
HYDRA_HELP = {"train"}  # `feeder train --help` is Hydra's own: its options are config overrides
SENTENCE_ENDS = (".", "?", "!")


def parsers_of(args: list[str], monkeypatch, capsys) -> list:
    """The argparse parser that `feeder ARGS --help` prints, and every subcommand parser below it."""
    import argparse

    shown = []
    original = argparse.ArgumentParser.print_help

    def record(self, file=None):
        shown.append(self)
        return original(self, file)

    monkeypatch.setattr(argparse.ArgumentParser, "print_help", record)
    try:
        assert main([*args, "--help"]) == 0
    except SystemExit as stop:
        assert stop.code in (0, None)
    capsys.readouterr()
    found, todo = [], list(shown)
    while todo:
        parser = todo.pop()
        found.append(parser)
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                todo += list(action.choices.values())
    return found


def help_commands() -> list[list[str]]:
    from feeder.cli import COMMANDS
    from feeder.figures import figure_names

    commands = [[name] for name in COMMANDS if name not in HYDRA_HELP and name != "figure"]
    return commands + [["figure", name] for name in figure_names()]


def test_every_help_is_whole_sentences_and_shows_every_default(monkeypatch, capsys):
    """Each command's description (and any subcommand's) ends a sentence; every option that is
    not required says its default in its help line."""
    import argparse

    problems = []
    for args in help_commands():
        parsers = parsers_of(args, monkeypatch, capsys)
        assert parsers, args
        if not (parsers[0].description or "").strip():
            problems.append(f"{parsers[0].prog}: no description")
        for parser in parsers:
            description = (parser.description or "").strip().split("\n\n")[0]  # a raw one ends in examples
            if description and not description.endswith(SENTENCE_ENDS):
                problems.append(f"{parser.prog}: description cut: ...{description[-40:]!r}")
            formatter = parser._get_formatter()
            for action in parser._actions:
                if not action.option_strings or action.required or action.default is argparse.SUPPRESS:
                    continue
                line = formatter._format_action(action)
                if "default" not in line.lower():
                    problems.append(f"{parser.prog} {'/'.join(action.option_strings)}: no default shown")
    assert not problems, "\n".join(problems)


def test_simulate_help_shows_the_defaults_of_its_design_and_preset(capsys):
    import pytest

    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    text = " ".join(capsys.readouterr().out.split())
    assert "(default: random)" in text and "--preset PRESET" in text and "(default: fast)" in text


# ---------------------------------------------------------------- broken pipes (issue 36, item 5)
def test_a_broken_pipe_ends_quietly_with_the_sigpipe_status(monkeypatch, capsys):
    import types

    from feeder import cli

    def write_to_closed_pipe(argv):
        raise BrokenPipeError(32, "Broken pipe")

    monkeypatch.setitem(cli.COMMANDS, "pipe-test", ("pipe_test_module", "a test command"))
    monkeypatch.setattr(cli.importlib, "import_module", lambda name: types.SimpleNamespace(main=write_to_closed_pipe))
    assert main(["pipe-test"]) == cli.SIGPIPE_STATUS == 141
    assert capsys.readouterr().err == ""


def test_commands_into_a_pipe_closed_early_end_quietly(tmp_path):
    """`feeder ... | head -1` with the reader gone before the command's first write: status 141
    (a process ended by SIGPIPE), no traceback. argparse's own --help swallows the write error
    (status 0)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    part = Path(__file__).resolve().parents[1] / "parts" / "rect-a2.stl"
    runs = {("--help",): {141}, ("parts", "list"): {141}, ("simulate", "--help"): {0, 141}}
    if part.is_file():
        runs[("features", str(part))] = {141}
    for args, statuses in runs.items():
        read, write = os.pipe()
        proc = subprocess.Popen([sys.executable, "-m", "feeder", *args], stdout=write, stderr=subprocess.PIPE)
        os.close(write)
        os.close(read)  # the reader is gone before the command writes
        _, err = proc.communicate(timeout=300)
        assert proc.returncode in statuses, (args, err)
        assert b"Traceback" not in err and b"BrokenPipe" not in err, (args, err)


def test_train_refuses_a_word_that_is_not_an_override_in_one_line(capsys):
    """`feeder train model --help` (a group name without =) used to print Hydra's traceback."""
    from feeder.learn.train import check_overrides

    assert main(["train", "model", "--help"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "'model' is not an override of the form key=value" in err[0]
    check_overrides(["model=m3", "--cfg", "job", "-m", "trainer.epochs=2", "+x=1", "~model.hidden"])  # all fine
    check_overrides(["--config-name", "train", "--info", "defaults"])  # option values are not overrides


def test_pull_overrides_moves_hydra_words_out_of_a_list_option(tmp_path):
    """A list option (nargs) takes every word after it: pull_overrides moves the key=value words
    that name no file to the overrides, keeps the rest in order, and keeps a file whose name holds '='."""
    from pathlib import Path

    from feeder.config import pull_overrides

    odd = tmp_path / "a=b"
    odd.mkdir()
    values = [Path("results/models/m3/seed0"), "protocol.fits=[main]", odd, "seed=3"]
    kept, overrides = pull_overrides(values, ["train.workers=1"])
    assert kept == [Path("results/models/m3/seed0"), odd]
    assert overrides == ["train.workers=1", "protocol.fits=[main]", "seed=3"]
    assert pull_overrides(None, ["x=1"]) == (None, ["x=1"])
    assert pull_overrides(["=odd"], []) == (["=odd"], [])
