"""Moved: the learning targets over seeds are the command ``coevo seeds`` (``coevo seeds --help``; it takes --jobs and --cluster)."""
