"""The toolkit's one exception family: each carries a single sentence saying what is wrong and what to do."""


class CartPoleError(Exception):
    """Base class of every error the toolkit raises on bad input; the CLI prints its message alone."""
