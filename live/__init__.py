"""Watching a running mission with the field's own tools: Groot2's monitor (:mod:`homing.live.groot2`)."""
