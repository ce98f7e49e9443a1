"""CLI subcommands: each module exposes ``register(subparsers)``.

A module's ``register`` adds one subparser and sets ``func`` to a callable
``(argparse.Namespace) -> int`` that returns the exit code.
"""
