"""The `strokekit` command: a click group whose commands live in cli/commands/*.py.

The front end parses, calls the library and reports. Library errors become one line on stderr
and an exit code (1 input or unwritable output, 2 usage, 3 partial failure); never a traceback unless
STROKEKIT_DEBUG=1."""

from __future__ import annotations

import os
import signal
import sys


def _aborted_while_starting(signum, frame):
    # Ctrl-C during the second or two of imports below: no traceback from deep inside them.
    sys.stderr.write("strokekit: aborted\n")
    os._exit(130)


if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
    signal.signal(signal.SIGINT, _aborted_while_starting)

import importlib  # noqa: E402
import pkgutil  # noqa: E402

import click  # noqa: E402

from strokekit.errors import StrokekitError  # noqa: E402

from . import commands  # noqa: E402
from .flags import user_message  # noqa: E402


class _Interrupted(Exception):
    """Ctrl-C inside a command, carried past click (which would print an empty line and abort)."""


class _Group(click.Group):
    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except KeyboardInterrupt:
            raise _Interrupted() from None


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 110})
@click.version_option(package_name="strokekit")
def cli():
    """Turn 3D scenes into coherent line drawings (SVG, JSON, glTF ribbons, toon masks)."""


for _info in sorted(pkgutil.iter_modules(commands.__path__), key=lambda m: m.name):
    _mod = importlib.import_module(f"{commands.__name__}.{_info.name}")
    _cmd = getattr(_mod, "command", None)
    if isinstance(_cmd, click.Command):
        cli.add_command(_cmd)


if signal.getsignal(signal.SIGINT) is _aborted_while_starting:
    signal.signal(signal.SIGINT, signal.default_int_handler)  # imports done: KeyboardInterrupt again


def main(argv: list[str] | None = None) -> None:
    try:
        rv = cli.main(args=argv, prog_name="strokekit", standalone_mode=False)
    except click.exceptions.Abort:
        click.echo("strokekit: aborted", err=True)
        sys.exit(130)
    except click.exceptions.NoArgsIsHelpError as e:
        click.echo(e.ctx.get_help() if e.ctx else str(e), err=True)
        sys.exit(2)
    except click.UsageError as e:
        # One line, as every other error; `--help` shows the usage.
        where = f" {e.ctx.command_path}" if e.ctx else ""
        click.echo(f"strokekit{where[len(' strokekit'):] if where.startswith(' strokekit') else where}: error: "
                   f"{e.format_message()} (see --help)", err=True)
        sys.exit(e.exit_code)
    except click.ClickException as e:
        e.show()
        sys.exit(e.exit_code)
    except StrokekitError as e:
        click.echo(f"strokekit: error: {user_message(e)}", err=True)
        sys.exit(e.exit_code)
    except (KeyboardInterrupt, _Interrupted):
        click.echo("strokekit: interrupted", err=True)
        sys.exit(130)
    except OSError as e:  # a file that cannot be read or written: a folder, no permission, disk full
        where = f"{e.filename}: " if e.filename else ""
        click.echo(f"strokekit: error: {where}{e.strerror or e}", err=True)
        sys.exit(1)
    except Exception as e:  # never a traceback for the user
        if os.environ.get("STROKEKIT_DEBUG"):
            raise
        click.echo(f"strokekit: internal error: {type(e).__name__}: {e} (set STROKEKIT_DEBUG=1 for details)", err=True)
        sys.exit(1)
    if argv is None:  # the command itself: the work is done and reported, exit as said
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    sys.exit(rv if isinstance(rv, int) else 0)


if __name__ == "__main__":
    main()
