"""One error policy for every command: an :class:`ArmgenError` prints its message and exits
with its code; a reader that closed the pipe (``armgen show x | head -1``) ends the command
quietly with 141 (128 + SIGPIPE, as a Unix tool killed by SIGPIPE); anything else is
reported as a bug in armgen."""

from __future__ import annotations

import functools
import os
import sys

import click

from ..api import ArmgenError, excerpt


def handle_errors(func):
    """Expected failures are ArmgenErrors with their exit code. Anything else is a bug in
    armgen: a short message (no traceback) and exit 1; ARMGEN_DEBUG=1 re-raises it."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        try:
            return func(*args, **kwargs)
        except ArmgenError as exc:
            click.echo(f"error: {exc}", err=True)
            sys.exit(exc.exit_code)
        except BrokenPipeError:
            # stdout's reader is gone: nothing more to say, and nothing for Python to flush at exit
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            sys.exit(141)
        except KeyboardInterrupt:
            click.echo("interrupted: no output was written", err=True)
            sys.exit(130)
        except Exception as exc:  # the last resort, not the mechanism: every known failure is an ArmgenError
            if os.environ.get("ARMGEN_DEBUG"):
                raise
            click.echo(f"internal error: {type(exc).__name__}: {excerpt(str(exc), 300)}\nThis is a bug in armgen; please "
                       "report it with the command line and the input files (ARMGEN_DEBUG=1 shows the traceback).",
                       err=True)
            sys.exit(1)
    return wrapper
