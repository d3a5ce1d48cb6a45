"""Recordings (`.jrec`): writer, reader and CSV export. See `jrec.py` for the format."""

from jointangle.recording.jrec import FORMAT_VERSION, MAGIC, JrecReader, JrecWriter, Record

__all__ = ["FORMAT_VERSION", "MAGIC", "JrecReader", "JrecWriter", "Record"]
