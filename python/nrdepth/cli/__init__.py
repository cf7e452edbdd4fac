"""The ``nrdepth`` command line: a thin layer over the Python API."""

from __future__ import annotations

import argparse
import sys
from typing import Optional, Sequence

from .. import __version__
from ..interrupt import raise_if_interrupted, sigint_remembered
from ..memory import keep_freed_memory
from . import data, job, learning


class _DefaultsFormatter(argparse.HelpFormatter):
    """Shows an option's default after its help, unless the help says it or there is none."""

    def _get_help_string(self, action: argparse.Action) -> str:
        text = action.help or ""
        if "default" in text or action.default in (None, False, argparse.SUPPRESS) or not action.option_strings:
            return text
        return f"{text} (default: {action.default})" if text else f"default: {action.default}"


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="nrdepth", description=__doc__)
    parser.add_argument("--version", action="version", version=f"nrdepth {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=lambda **kw: argparse.ArgumentParser(formatter_class=_DefaultsFormatter, **kw))

    data.add_commands(sub)
    learning.add_commands(sub)
    job.add_commands(sub)
    return parser


VALUE_MAY_START_WITH_DASH = ("--roi", "--frames", "--light-azimuth")
"""Options whose value can begin with '-' (a negative number): argparse would
take ``--roi -10,0,9,9`` for two options, so such pairs are joined with '='."""


def _join_dash_values(argv: Sequence[str]) -> list:
    joined, i = [], 0
    while i < len(argv):
        if argv[i] in VALUE_MAY_START_WITH_DASH and i + 1 < len(argv) and argv[i + 1].startswith("-") and argv[i + 1][1:2].isdigit():
            joined.append(f"{argv[i]}={argv[i + 1]}")
            i += 2
        else:
            joined.append(argv[i])
            i += 1
    return joined


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = build_parser()
    args = parser.parse_args(_join_dash_values(sys.argv[1:] if argv is None else list(argv)))
    try:
        with sigint_remembered():
            code = args.run(args)
            raise_if_interrupted()
        return code
    except (ValueError, TypeError, OSError, ImportError) as e:  # ImportError: an optional dependency, named with its pip extra
        print(f"nrdepth {args.command}: error: {e}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"nrdepth {args.command}: interrupted", file=sys.stderr)
        return 130


def run() -> int:
    """The ``nrdepth`` command: :func:`main` in a process of its own, whose
    C heap keeps what it frees (:func:`~nrdepth.memory.keep_freed_memory`:
    the fine pass's activations reused, not faulted in again)."""
    keep_freed_memory()
    return main()


if __name__ == "__main__":
    sys.exit(run())
