"""Benchmarks behind ``homing bench NAME``: one module per benchmark.

A module here that defines ``add_arguments(parser)`` and ``run(args) -> int``
becomes ``homing bench <module>``; ``--json PATH`` is added for it. Each prints
a table and writes the JSON keys its issue names. Never collected by pytest.
"""
