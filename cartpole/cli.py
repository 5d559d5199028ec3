"""The ``cartpole`` command line: one subcommand per module in :mod:`cartpole.commands`.

Every subcommand takes ``--mjcf PATH`` (default: the shipped asset) and ``--json`` (print exactly one JSON document
on stdout, nothing else); those that write files take ``--out DIR`` (default: the current directory), checked
before any work. Bad input ends with one sentence on stderr and exit status 2, never a traceback, and leaves the
``--out`` tree as it was (:func:`cartpole._files.output_transaction`). Long stages report on stderr through
:mod:`cartpole.progress` (a live bar on a terminal, one line per stage otherwise, nothing with ``--json``).
"""
from __future__ import annotations

import argparse
import contextlib
import ctypes
import importlib
import json
import os
import signal
import sys
import threading
import warnings
from pathlib import Path

from cartpole._files import atomic_write, check_out_dir, output_transaction
from cartpole.apps import forkserver
from cartpole.commands._flags import as_flags
from cartpole.errors import CartPoleError, Terminated, first_line
from cartpole.progress import reporting

#: Subcommand modules, in the order ``cartpole --help`` lists them (one per line: add a command with one line).
COMMANDS = (
    "linearize",
    "lqr",
    "swingup",
    "feedforward",
    "sweep",
    "bench",
    "excite",
    "identify",
    "export",
    "score",
    "library",
)


class _Parser(argparse.ArgumentParser):
    """argparse with its errors as one line (``cartpole swingup: argument --x0: ...; see --help``), exit 2."""

    def error(self, message):
        self.exit(2, f"{self.prog}: {message}; see `{self.prog} --help`.\n")


def _load_commands():
    return {name: importlib.import_module(f"cartpole.commands.{name}") for name in COMMANDS}


def sentence(exc: BaseException) -> str:
    """The error's message as one line ending in a full stop (:func:`cartpole.errors.first_line`)."""
    text = first_line(exc)
    return text if text.endswith(".") else text + "."


def writes_files(mod) -> bool:
    """Whether a command module writes files (``WRITES_FILES``, default True): only those take ``--out``."""
    return bool(getattr(mod, "WRITES_FILES", True))


def build_parser() -> argparse.ArgumentParser:
    """The argument parser with every available subcommand and the common options."""
    parser = _Parser(prog="cartpole", description=__doc__.splitlines()[0])
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    sub.required = True
    for name, mod in _load_commands().items():
        p = sub.add_parser(name, help=mod.HELP, description=getattr(mod, "DESCRIPTION", mod.HELP))
        p.add_argument("--mjcf", default=None, metavar="PATH",
                       help="cart-pole MJCF file, or a URDF (default: the shipped cartpole/assets/cartpole.xml)")
        p.add_argument("--actuated-joint", action="append", default=None, metavar="NAME", dest="actuated_joint",
                       help="URDF only, repeatable: put a motor (ctrl = the joint's force or torque, limited by its "
                            "effort) on this joint, overriding the file's <transmission> elements (default: the "
                            "transmissions, else the only prismatic joint)")
        if writes_files(mod):
            p.add_argument("--out", default=".", metavar="DIR",
                           help="directory for outputs, created if missing (default: .)")
        else:  # removed (it was ignored): parsed only to say so in one sentence
            p.add_argument("--out", default=None, help=argparse.SUPPRESS)
        p.add_argument("--json", action="store_true", help="print one JSON document on stdout instead of prose")
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run, _writes=writes_files(mod))
    return parser


def to_jsonable(obj):
    """Convert numpy arrays/scalars and paths inside ``obj`` to plain JSON types."""
    import numpy as np

    if isinstance(obj, dict):
        return {str(k): to_jsonable(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [to_jsonable(v) for v in obj]
    if isinstance(obj, np.ndarray):
        return to_jsonable(obj.tolist())
    if isinstance(obj, (np.floating,)):
        obj = float(obj)
    if isinstance(obj, (np.integer,)):
        return int(obj)
    if isinstance(obj, (np.bool_,)):
        return bool(obj)
    if isinstance(obj, float) and not np.isfinite(obj):
        return None
    if isinstance(obj, Path):
        return str(obj)
    return obj


@contextlib.contextmanager
def _stdout_to_stderr():
    """Send everything written to stdout inside the block to stderr: Python's ``print`` and, at the file-descriptor
    level, what C libraries print (LAPACK's XERBLA, a solver's banner), so the one JSON document stays alone."""
    if sys.stdout is not None:
        sys.stdout.flush()
    try:
        saved = os.dup(1)
        os.dup2(2, 1)
    except OSError:  # no file descriptor 1 or 2: nothing to protect
        saved = None
    try:
        with contextlib.redirect_stdout(sys.stderr):
            yield
    finally:
        sys.stderr.flush()
        if saved is not None:
            try:
                ctypes.CDLL(None).fflush(None)  # C stdio buffers still holding output meant for the old fd 1
            except (OSError, AttributeError):
                pass
            os.dup2(saved, 1)
            os.close(saved)


def _run(args, received: SignalsReceived | None = None):
    """Run the command inside its progress reporter (and, when it writes files, its output transaction); a signal
    in ``received`` whose exception a library swallowed stops it at the end, inside the transaction."""
    from cartpole.codegen import private_cache_dir  # heavy (NumPy, CasADi): imported once a command runs
    from cartpole.models import mujoco_warnings

    try:  # a cache another user owns or may write to is refused before any work (CacheError, one sentence)
        private_cache_dir()
    except OSError:  # it cannot be created: the commands run without it (compiled code falls back)
        pass
    notes: list[str] = []
    with contextlib.ExitStack() as stack:
        # NumPy's and SciPy's warnings (an overflow inside a Riccati solve, say) are kept, not printed as they come:
        # a failing command prints its one sentence alone, a successful one each distinct warning once at the end
        caught = stack.enter_context(warnings.catch_warnings(record=True))
        warnings.simplefilter("default")
        if args._writes:
            args.out = str(check_out_dir(args.out))
            stack.enter_context(output_transaction())
        elif args.out is not None:
            raise CartPoleError(f"--out was removed from {args.command}: {args.command} writes no files; drop the "
                                "option")
        stack.enter_context(mujoco_warnings(notes.append))  # not MUJOCO_LOG.TXT in the cwd: not ours to write
        imports = stack.enter_context(_urdf_session(args))
        stack.enter_context(reporting(args.command, enabled=not args.json))
        if args.json:  # a stray print must not spoil the one JSON document
            stack.enter_context(_stdout_to_stderr())
        doc = args._run(args)
        if args._writes:  # inside the output transaction: the MJCF each URDF ran as, so its logs replay
            _write_urdf_mjcf(imports, Path(args.out), doc)
        if received is not None:  # its files are removed as for any failure
            received.raise_if_any()
    _report_urdf(args.command, imports, doc)
    for note in dict.fromkeys(notes):  # each distinct warning once, after a run that succeeded
        print(f"cartpole {args.command}: MuJoCo warned: {note}", file=sys.stderr)
    for note in dict.fromkeys(f"{w.category.__name__}: {' '.join(str(w.message).split())}" for w in caught):
        print(f"cartpole {args.command}: warning: {note}", file=sys.stderr)
    return doc


def _urdf_session(args):
    """The URDF choices of ``--actuated-joint`` for every model the command reads (refused for an MJCF), collecting
    what each URDF read added (:func:`cartpole.models.urdf_session`)."""
    from cartpole.models import is_urdf, urdf_session

    chosen = getattr(args, "actuated_joint", None)
    if chosen and getattr(args, "mjcf", None) is not None:
        try:
            text = Path(args.mjcf).expanduser().read_text()
        except (OSError, UnicodeDecodeError):
            text = None  # the command's own reading says what is wrong with the file
        if text is not None and not is_urdf(text):
            raise CartPoleError(f"--actuated-joint chooses the driven joints of a URDF, and --mjcf {args.mjcf} is "
                                "an MJCF with its own actuators; drop --actuated-joint or edit the MJCF's <actuator>")
    elif chosen:
        raise CartPoleError("--actuated-joint chooses the driven joints of a URDF, and no --mjcf was given (the "
                            "shipped MJCF has its own motor); give --mjcf with a URDF or drop --actuated-joint")
    return urdf_session(chosen, option="--actuated-joint NAME")


def _write_urdf_mjcf(imports: list, out: Path, doc) -> None:
    """Write the MJCF text each URDF ran as (its motors added) to ``out/model/<name>_mujoco.xml`` and name it in
    the JSON document's ``model.mjcf_ran``: MuJoCo reads a URDF without its transmissions, so only this file replays
    the logged ctrl."""
    written = []
    for rec in imports:
        if not rec.mjcf:
            continue
        stem = Path(rec.path).stem if rec.path else "urdf"
        path = atomic_write(out / "model" / f"{stem}_mujoco.xml", lambda fh, text=rec.mjcf: fh.write(text.encode()))
        written.append(str(path.resolve()))
    if written and isinstance(doc, dict) and isinstance(doc.setdefault("model", {}), dict):
        doc["model"]["mjcf_ran"] = written[0] if len(written) == 1 else written


def _report_urdf(command: str, imports: list, doc) -> None:
    """Say what reading a URDF added: one sentence per motor and change on stderr, and in the JSON document under
    ``model``: ``actuators_added`` (one object per motor, with its ``file``) and ``urdf_changes`` (sentences)."""
    if not imports:
        return
    for rec in imports:
        for line in rec.sentences():
            print(f"cartpole {command}: {line}", file=sys.stderr)
    if isinstance(doc, dict):
        model = doc.setdefault("model", {})
        if isinstance(model, dict):
            model["actuators_added"] = [{**a.to_dict(), "file": rec.path} for rec in imports for a in rec.actuators]
            model["urdf_changes"] = [line for rec in imports for line in rec.sentences()[len(rec.actuators):]]


class SignalsReceived:
    """The signals received inside :func:`signals_as_interrupts`, in order (``signums``).

    Once one has come, whatever exception ends the command is that signal's: the handler's own exception may reach
    the top as another type, e.g. a TypeError where pybind11 was converting a call's arguments when the signal came,
    or be swallowed by a library's ``except Exception`` (the command then stops when it returns,
    :meth:`raise_if_any`).
    """

    def __init__(self):
        self.signums: list[int] = []

    @property
    def signum(self) -> int | None:
        """The first signal received (its number), None if none was."""
        return self.signums[0] if self.signums else None

    def exception(self) -> KeyboardInterrupt:
        """What the first signal raises: :class:`Terminated` for SIGTERM and SIGHUP, KeyboardInterrupt for SIGINT."""
        return KeyboardInterrupt() if self.signum == signal.SIGINT else Terminated(self.signum)

    def raise_if_any(self) -> None:
        """Raise :meth:`exception` if a signal was received (one whose exception a library swallowed)."""
        if self.signums:
            raise self.exception()


@contextlib.contextmanager
def signals_as_interrupts(received: SignalsReceived | None = None):
    """Inside the block (in the main thread), SIGTERM and SIGHUP raise :class:`Terminated`, and SIGINT (where its
    handler is Python's own) KeyboardInterrupt; each signal is recorded in ``received`` (a new
    :class:`SignalsReceived` if None, yielded). Only the first raises: a second one while the command unwinds is
    only recorded, so its clean-up (the half-written files removed, the encoder and the workers stopped) finishes.
    The handlers before are put back afterwards; a signal that was ignored stays ignored."""
    received = SignalsReceived() if received is None else received
    if threading.current_thread() is not threading.main_thread():
        yield received
        return

    def interrupt(signum, frame):
        received.signums.append(signum)
        if len(received.signums) == 1:
            raise received.exception()

    saved = {}
    for sig in (signal.SIGTERM, signal.SIGHUP):
        if signal.getsignal(sig) is not signal.SIG_IGN:
            saved[sig] = signal.signal(sig, interrupt)
    if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        saved[signal.SIGINT] = signal.signal(signal.SIGINT, interrupt)
    try:
        yield received
    finally:
        for sig, handler in saved.items():
            signal.signal(sig, handler)


def _start_sweep_workers_early(argv: list) -> None:
    """For ``cartpole sweep --workers W`` (W > 1, no ``--address``): start the pool's fork server now, before this
    process imports NumPy, SciPy, CasADi and MuJoCo to build its parser and its model, so that the server imports
    the toolkit for the workers at the same time (:func:`cartpole.apps.forkserver.start_server`). Anything unusual
    (another command, a bad number) is left to the real parser."""
    if not argv or argv[0] != "sweep":
        return

    peek = argparse.ArgumentParser(add_help=False)
    peek.add_argument("--workers", type=int, default=1)
    peek.add_argument("--address", default=None)
    peek.add_argument("--method", action="append", default=None)
    try:
        known, _ = peek.parse_known_args(argv[1:])
    except (SystemExit, ValueError):
        return
    if known.workers > 1 and not known.address:
        forkserver.start_server((known.method or ["energy"])[0])


def main(argv=None) -> int:
    """Entry point of the ``cartpole`` console script; returns the exit status."""
    # Headless rendering: MUJOCO_GL must be set before mujoco is first imported.
    os.environ.setdefault("MUJOCO_GL", "egl")
    _start_sweep_workers_early(sys.argv[1:] if argv is None else list(argv))
    parser = build_parser()
    try:
        args, extra = parser.parse_known_args(argv)
    except SystemExit as exc:  # --help (0) or a bad option (2, one line already printed)
        return exc.code if isinstance(exc.code, int) else 2
    if extra:
        print(f"cartpole {args.command}: unrecognized arguments: {' '.join(extra)}; see `cartpole {args.command} "
              "--help`.", file=sys.stderr)
        return 2
    if os.environ.get("MPLBACKEND"):  # matplotlib refuses a bad one at import, with a traceback: say it here
        try:
            import matplotlib  # noqa: F401
        except ValueError:
            print(f"cartpole {args.command}: MPLBACKEND={os.environ['MPLBACKEND']!r} is not a matplotlib backend; "
                  "unset it or set MPLBACKEND=Agg (the figures are written to files).", file=sys.stderr)
            return 2
    try:
        import mujoco  # noqa: F401  (MuJoCo 4 raises AttributeError, not ImportError, for a missing GL library)
    except Exception as exc:  # pragma: no cover - depends on the machine's GL libraries
        print(f"cartpole {args.command}: MuJoCo failed to load with MUJOCO_GL={os.environ.get('MUJOCO_GL')} "
              f"({type(exc).__name__}); set MUJOCO_GL=egl (or unset it) and try again.", file=sys.stderr)
        return 2
    received = SignalsReceived()
    try:
        with signals_as_interrupts(received):
            doc = _run(args, received)
    except BaseException as exc:
        status = _failure(args.command, exc, received.signum)
        if status is None:
            raise
        return status
    if args.json:
        return _print_document(args.command, doc)
    return 0


def _failure(command: str, exc: BaseException, signum: int | None) -> int | None:
    """Print the one sentence for the exception that ended ``command`` on stderr and return the exit status (None:
    not one of ours, let it be raised). After signal ``signum`` (None: no signal came) any exception is that
    signal's: the handler's own may have surfaced as another type (pybind11 turns it into a TypeError when the
    signal comes while it converts arguments); the output transaction has removed the command's files already."""
    if signum is not None or isinstance(exc, KeyboardInterrupt):
        return _interrupted(command, exc, signum)
    if isinstance(exc, CartPoleError):  # the library names Python arguments; the command line prints their options
        print(f"cartpole {command}: {as_flags(sentence(exc))}", file=sys.stderr)
    elif isinstance(exc, MemoryError):
        print(f"cartpole {command}: ran out of memory; give a shorter --duration or fewer runs.", file=sys.stderr)
    elif isinstance(exc, OSError):  # a file-system failure outside cartpole._files (its own are OutputError)
        where = f" {exc.filename}" if getattr(exc, "filename", None) else ""
        print(f"cartpole {command}: cannot read or write{where} ({exc.strerror or sentence(exc)[:-1]}); "
              "check the path or choose another --out.", file=sys.stderr)
    else:
        return None
    return 2


def _interrupted(command: str, exc: BaseException, signum: int | None) -> int:
    """Ctrl-C or a signal: the command's own sentence when it gave one (a sweep says what it kept and how to go
    on), else a stock one; exit status 130 for Ctrl-C, 128 + the signal's number for SIGTERM and SIGHUP."""
    if isinstance(exc, Terminated):
        signum = exc.signum
    elif signum is None:  # a KeyboardInterrupt that no handler of ours raised
        signum = signal.SIGINT
    said = exc.args[0] if isinstance(exc, KeyboardInterrupt) and exc.args and isinstance(exc.args[0], str) else None
    if signum == signal.SIGINT:
        print(f"cartpole {command}: {said or 'interrupted.'}", file=sys.stderr)
        return 130
    said = said or f"stopped by {signal.Signals(signum).name} before it finished; no partial output is left."
    print(f"cartpole {command}: {said}", file=sys.stderr)
    return 128 + signum


def _print_document(command: str, doc) -> int:
    """Write the JSON document on stdout; a stdout that is closed, full or a pipe whose reader left is one sentence
    on stderr (or, for the pipe, silence and status 141, as SIGPIPE would end a Unix tool), never a traceback."""
    text = json.dumps(to_jsonable(doc)) + "\n"
    try:
        if sys.stdout is None:
            raise OSError(9, "stdout is closed")
        sys.stdout.write(text)
        sys.stdout.flush()
    except BrokenPipeError:
        try:  # nothing more can reach the reader; keep the interpreter's own flush at exit quiet too
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        except (OSError, AttributeError, ValueError):
            pass
        return 141
    except OSError as exc:
        print(f"cartpole {command}: cannot write the JSON document to stdout ({exc.strerror or exc}); check where "
              "stdout goes (a full disk, a closed descriptor).", file=sys.stderr)
        try:
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 1)
        except OSError:
            pass
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
