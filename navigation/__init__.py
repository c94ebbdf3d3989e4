"""Navigation: costmaps, global planners, local controllers and recoveries, chosen by name."""
