"""The `dvsot` command line: dispatches to the sub-command modules in `dvsot.cli`."""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
import warnings

from dvsot.runtime import interrupts

if sys.argv and (sys.argv[0] == "-m" or os.path.basename(sys.argv[0]) == "dvsot"):  # the dvsot command starting
    interrupts.at_startup()  # a signal during the imports below ends it with one line, not an import's traceback

from dvsot import __version__  # noqa: E402
from dvsot.cli.flags import flag_labels
from dvsot.core.errors import RunError, UserError

# name -> module; the module's docstring's first line is the help text.
COMMANDS: dict[str, str] = {
    "generate": "dvsot.cli.generate",
    "simulate": "dvsot.cli.simulate",
    "info": "dvsot.cli.info",
    "train": "dvsot.cli.train",
    "bench": "dvsot.cli.bench",
    "export": "dvsot.cli.export",
    "import": "dvsot.cli.import_",
    "export-model": "dvsot.cli.export_model",
}


class _Parser(argparse.ArgumentParser):
    """argparse, with a bad flag reported in one line (not the usage block first), exit status 2."""

    def error(self, message: str):
        self.exit(2, f"{self.prog}: error: {' '.join(message.split())} (see {self.prog} --help)\n")


def build_parser() -> argparse.ArgumentParser:
    """The full argument parser, one sub-parser per command module that is present."""
    parser = _Parser(prog="dvsot", description=__doc__)
    parser.add_argument("--version", action="version", version=f"dvsot {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name, module_name in COMMANDS.items():
        try:
            module = importlib.import_module(module_name)
        except ModuleNotFoundError as exc:
            if exc.name == module_name:
                continue  # command not built yet
            raise
        doc = (module.__doc__ or "").strip().splitlines()
        p = sub.add_parser(name, help=doc[0] if doc else None, description=(module.__doc__ or None),
                           formatter_class=argparse.RawDescriptionHelpFormatter)
        module.add_arguments(p)
        p.set_defaults(_run=module.run, param_flags=flag_labels(p))  # library parameter -> this command's flag
    return parser


def _close_progress_bars() -> None:
    """Close every live tqdm bar now (its last state stays on screen), so nothing is drawn after our message."""
    tqdm = sys.modules.get("tqdm")
    for bar in list(getattr(getattr(tqdm, "tqdm", None), "_instances", None) or []):
        bar.close()


def _one_line_warnings(prog: str) -> None:
    """Show each warning as one stderr line "prog: note: message" (Python's default adds the source line)."""

    def show(message, category, filename, lineno, file=None, line=None) -> None:
        print(f"{prog}: note: {' '.join(str(message).split())}", file=file or sys.stderr)

    warnings.showwarning = show


def _stdout_closed() -> int:
    """The reader of stdout has gone: say nothing more, and exit as a tool killed by SIGPIPE does (128 + 13)."""
    devnull = os.open(os.devnull, os.O_WRONLY)
    os.dup2(devnull, sys.stdout.fileno())  # Python's final flush of the unwritten rest then goes nowhere
    os.close(devnull)
    return 128 + signal.SIGPIPE


def main(argv: list[str] | None = None) -> int:
    """Run the command line; bad input prints one line and returns 2."""
    command = interrupts.is_command() and argv is None
    status = 1
    try:
        status = _main(argv)
        return status
    finally:
        if command:  # the process exits next (Blender's clean-up may take a while): its status is decided
            interrupts.after_command("dvsot " + next((a for a in sys.argv[1:] if a in COMMANDS), ""), status)


def _main(argv: list[str] | None) -> int:
    saved = interrupts.install()  # SIGTERM is handled as SIGINT is: outputs cleaned up, one line, 128 + signal
    try:
        parser = build_parser()
        args = parser.parse_args(argv)
    except BaseException as caught:
        if isinstance(caught, SystemExit) or (interrupts.interruption(caught) is None and not interrupts.seen()):
            interrupts.restore(saved)
            raise
        interrupts.restore(saved)
        signum = interrupts.seen() or signal.SIGINT
        print(f"dvsot: interrupted ({signal.Signals(signum).name})", file=sys.stderr)
        return 128 + signum
    _one_line_warnings(f"dvsot {args.command}")
    interrupted = False
    try:
        status = int(args._run(args) or 0)
        if interrupts.late():  # its outputs were all in place before the signal: the run succeeded
            print(f"dvsot {args.command}: done; {signal.Signals(interrupts.late()).name} arrived after its outputs "
                  "were written", file=sys.stderr)
        sys.stdout.flush()  # a reader that closed the pipe (`| head -1`) shows here, not at interpreter exit
        return status
    except BrokenPipeError:
        return _stdout_closed()
    except UserError as exc:
        _close_progress_bars()  # a bar left open would redraw itself under the message at exit
        print(f"dvsot {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except RunError as exc:
        _close_progress_bars()
        print(f"dvsot {args.command}: failed: {exc}", file=sys.stderr)
        return 1
    except (SystemExit, GeneratorExit):
        raise
    except BaseException as caught:
        _close_progress_bars()  # else each redraws itself at exit, under the message
        status = interrupts.stopped_status(caught, f"dvsot {args.command}")
        if status is None:  # an exception of its own
            raise
        interrupted = True
        return status
    finally:
        interrupts.restore(saved)
        if interrupted:
            interrupts.quiet_exit()

