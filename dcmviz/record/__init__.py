"""Rerun recordings of a walking session (:mod:`.recorder`): an ``.rrd`` file the rerun viewer
opens, written while the session runs."""

from dcmviz.record.recorder import Recorder, record_session

__all__ = ["Recorder", "record_session"]
