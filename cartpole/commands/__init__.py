"""One module per ``cartpole`` subcommand; each defines ``HELP``, ``add_arguments(parser)`` and
``run(args) -> dict`` (the JSON document; prose goes to stdout only when ``args.json`` is false)."""
