"""Run logs as MCAP files that Foxglove Studio and the ``mcap`` tools open without ROS.

:class:`McapLogger` writes any cufund message (and user dataclasses) while a run goes, at about a microsecond
per message and in bounded memory; :func:`read_mcap` gives the same message objects back, bit for bit.
"""

from .mcap_reader import LogRecord, McapReadError, log_metadata, log_topics, read_mcap
from .mcap_writer import McapLogger

__all__ = ["LogRecord", "McapLogger", "McapReadError", "log_metadata", "log_topics", "read_mcap"]
