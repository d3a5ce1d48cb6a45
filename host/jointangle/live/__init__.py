"""Talking to a running device: streaming sessions and the live readout. See `stream.py`
(sessions that survive a pulled cable), `session.py` (the numbers behind the readout),
`host_filter.py` (a host estimator beside the board's) and `view.py` (the terminal readout).
What the board's hello, readings and filter mean is in `jointangle.device`."""
