"""Behaviours: thin py_trees leaves and decorators over the modules, through the blackboard."""
