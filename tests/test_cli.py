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
