"""``coevo seeds``: Tracking and Docking learned offline over seeds, against the learning targets."""
