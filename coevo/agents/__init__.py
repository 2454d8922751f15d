"""GA workers, one process per behaviour, on Eclipse Zenoh (the service issue; not built yet).

The wire protocol they will speak is already in :mod:`coevo.keys` and :mod:`coevo.messages`.
"""
