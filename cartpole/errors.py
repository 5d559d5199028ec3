"""The toolkit's one exception family: each carries a single sentence saying what is wrong and what to do."""


class CartPoleError(Exception):
    """Base class of every error the toolkit raises on bad input; the CLI prints its message alone."""


def elide(text: str, width: int) -> str:
    """``text`` with its middle replaced by ``...`` when longer than ``width`` characters: the start and the end
    are kept (for a path, the root and the file name; for a message, what it is about and its last words).

    Parameters
    ----------
    text : str
    width : int
        Largest length returned (at least 9).

    Returns
    -------
    str
    """
    text = str(text)
    width = max(int(width), 9)
    if len(text) <= width:
        return text
    head = (width - 3) // 3
    return text[:head] + "..." + text[len(text) - (width - 3 - head):]


def first_line(exc: BaseException, width: int | None = None) -> str:
    """A (often multi-line, e.g. MuJoCo's) exception message folded into one line, without a final period.

    Never cut at the end: with ``width`` (for another library's message set inside one of ours) a longer message
    loses its middle (:func:`elide`), so its last words stay; without it the whole message is kept, so the advice
    that ends a toolkit sentence is always printed.
    """
    msg = " ".join(part.strip() for part in str(exc).strip().splitlines() if part.strip())
    msg = msg.replace(": Error=", ": ").rstrip(".")
    if not msg:
        return type(exc).__name__
    return msg if width is None else elide(msg, width)


#: Width a foreign message (MuJoCo's, the file system's) keeps inside one of the toolkit's sentences.
FOREIGN_WIDTH = 240


class Terminated(KeyboardInterrupt):
    """SIGTERM (or SIGHUP) received by the command line (:func:`cartpole.cli.signals_as_interrupts`): raised in the
    main thread like Ctrl-C's KeyboardInterrupt, so every ``finally`` runs, the output transaction removes what the
    command had written, worker pools and encoders are shut down; the process exits with status 128 + ``signum``.
    ``args[0]``, when given, is the sentence to print (what was kept, how to go on)."""

    def __init__(self, signum: int, *args):
        super().__init__(*args)
        self.signum = int(signum)
