"""The toolkit's one exception family: each carries a single sentence saying what is wrong and what to do."""


class CartPoleError(Exception):
    """Base class of every error the toolkit raises on bad input; the CLI prints its message alone."""


def first_line(exc: BaseException) -> str:
    """A (often multi-line, e.g. MuJoCo's) exception message folded into one line, without a final period.

    Capped at 240 characters so that it fits in the one sentence the toolkit prints.
    """
    msg = " ".join(part.strip() for part in str(exc).strip().splitlines() if part.strip())
    msg = msg.replace(": Error=", ": ").rstrip(".")
    return (msg[:240] + "...") if len(msg) > 240 else (msg or type(exc).__name__)


class Terminated(KeyboardInterrupt):
    """SIGTERM (or SIGHUP) received by the command line (:func:`cartpole.cli.signals_as_interrupts`): raised in the
    main thread like Ctrl-C's KeyboardInterrupt, so every ``finally`` runs, the output transaction removes what the
    command had written, worker pools and encoders are shut down; the process exits with status 128 + ``signum``.
    ``args[0]``, when given, is the sentence to print (what was kept, how to go on)."""

    def __init__(self, signum: int, *args):
        super().__init__(*args)
        self.signum = int(signum)
