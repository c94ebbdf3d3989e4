"""Missions: the YAML mission language, the runner, the terminal view and the CLI."""
