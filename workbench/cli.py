"""The ``workbench`` command line (CONTRACTS.md section 3): thin over the library.

Exit status 0 on success, 2 on bad input with a one-line reason on standard error.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

from . import __version__
from .assembly import assemble
from .frame import read_frame
from .modal import model_modes
from .outputs import OutputExistsError, csv_text, write_outputs

__all__ = ["main"]


class _Parser(argparse.ArgumentParser):
    def error(self, message: str) -> None:  # one line and exit 2, as for any bad input
        self.exit(2, f"{self.prog}: error: {message}\n")


def _positive_int(text: str) -> int:
    value = int(text)
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a positive integer, got {text}")
    return value


def _modes(args: argparse.Namespace) -> str:
    model = assemble(read_frame(args.frame))
    modes = model_modes(model, args.count)
    text = csv_text(["mode", "frequency_hz"],
                    ((k + 1, float(f)) for k, f in enumerate(modes.frequency_hz)))
    write_outputs(args.out, {"modes.csv": text}, force=args.force)
    return f"{modes.count} modes of {model.frame.name!r} ({model.size} dofs) written to {args.out}/modes.csv"


def _parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="workbench", description=__doc__.splitlines()[0])
    parser.add_argument("--version", action="version", version=f"workbench {__version__}")
    sub = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)

    p = sub.add_parser("modes", help="nominal eigenfrequencies of a frame file (joints at their mean)")
    p.add_argument("frame", help="frame.toml (CONTRACTS.md section 1)")
    p.add_argument("--count", type=_positive_int, default=10, help="number of modes (default 10)")
    p.add_argument("--out", required=True, help="output directory (created if absent)")
    p.add_argument("--force", action="store_true", help="replace existing files in --out")
    p.set_defaults(run=_modes)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; returns the exit status."""
    try:
        args = _parser().parse_args(argv)
    except SystemExit as exc:  # usage errors (exit 2) and --help (exit 0) return like the rest
        return int(exc.code or 0)
    start = time.perf_counter()
    try:
        message = args.run(args)
    except (ValueError, KeyError, OutputExistsError, OSError) as exc:
        text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
        print(f"workbench {args.command}: {' '.join(str(text).split())}", file=sys.stderr)
        return 2
    print(f"{message} in {time.perf_counter() - start:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
