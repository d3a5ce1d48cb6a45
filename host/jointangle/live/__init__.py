"""Talking to a running device: streaming sessions, the firmware's view of its inputs, the live
readout. See `stream.py` (sessions that survive a pulled cable), `device.py` (hello, firmware
readings, mirror verification) and `view.py` (the terminal readout)."""
