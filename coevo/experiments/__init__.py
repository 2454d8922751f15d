"""Small self-contained experiments that reproduce the report's appendices beside the robot tasks."""
