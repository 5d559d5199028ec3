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
