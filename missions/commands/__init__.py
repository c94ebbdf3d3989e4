"""Subcommands of ``homing``: each module defines ``register(subparsers)``.

``register`` adds one parser (with ``help=`` and a ``--help`` of its own) and
sets ``func=`` to a callable ``args -> int``. Heavy imports go inside ``func``.
"""
