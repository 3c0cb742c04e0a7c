"""Every leaf command of the ``bellows`` app: ``{"paper workspace": click command, ...}`` (tests walk it to check
each command's options and help)."""

import typer

from validation.commands.main import app


def commands() -> dict:
    def walk(cmd, prefix=()):
        if hasattr(cmd, "commands"):
            for name, sub in cmd.commands.items():
                yield from walk(sub, prefix + (name,))
        else:
            yield " ".join(prefix), cmd
    return dict(walk(typer.main.get_command(app)))
