"""``coevo dashboard``: a read-only web page of the runs on the bus, their curves, and comparisons in progress.

``model`` gathers what the page shows as plain data (runs, workers, learning curves, a
comparison's replicates and Table 1) from the bus, through :class:`coevo.bus.status.StatusBoard`,
and from run and comparison directories; ``render`` turns it into the page's pieces (HTML
tables, plot lines) without a web library; ``server`` is the Bokeh server that shows them and
``command`` the command line.  Nothing is imported here, so ``coevo dashboard --help`` loads
neither Zenoh nor Bokeh.
"""
