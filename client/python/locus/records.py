"""Plain Python views of the farm's answers (proto/locus.proto).

Each record has one attribute per field of its message, under the field's
proto name: repeated fields are lists, nested messages dicts, a job's
`state` a word ("queued", "running", "paused", "succeeded", "failed",
"cancelled"). The message itself stays in `.proto`.
"""

from google.protobuf.descriptor import FieldDescriptor

from .proto import locus_pb2

#: The states a job never leaves (except by `retry` or `requeue`).
FINISHED_STATES = ("succeeded", "failed", "cancelled")

_STATE_PREFIX = "JOB_STATE_"


def _value(message, field):
    value = getattr(message, field.name)
    if field.label == FieldDescriptor.LABEL_REPEATED:
        if field.type == FieldDescriptor.TYPE_MESSAGE:
            return [_as_dict(m) for m in value]
        return list(value)
    if field.type == FieldDescriptor.TYPE_MESSAGE:
        return _as_dict(value)
    return value


def _as_dict(message):
    return {f.name: _value(message, f) for f in message.DESCRIPTOR.fields}


def state_name(state):
    """The word for a JobState: "running" for JOB_STATE_RUNNING, and so on."""
    name = locus_pb2.JobState.Name(state)
    return name[len(_STATE_PREFIX):].lower() if name.startswith(_STATE_PREFIX) else name.lower()


class Record:
    """The fields of one message as attributes; `.proto` is the message."""

    def __init__(self, message):
        self.proto = message
        for field in message.DESCRIPTOR.fields:
            setattr(self, field.name, _value(message, field))

    def as_dict(self):
        """The fields as a dict (nested messages as dicts too)."""
        return {f.name: getattr(self, f.name) for f in self.proto.DESCRIPTOR.fields}

    def __eq__(self, other):
        return type(self) is type(other) and self.proto == other.proto

    def __repr__(self):
        shown = ", ".join(f"{k}={v!r}" for k, v in self._summary().items())
        return f"{type(self).__name__}({shown})"

    def _summary(self):
        return self.as_dict()


class JobStatus(Record):
    """A job's status (message JobStatus): job_id, state, owner, priority,
    scene_name, output, width, height, frame_first, frame_last,
    bands_per_frame, bands_total, bands_done, bands_running, frames_total,
    frames_done, frames_written, error, waiting, seconds_elapsed, stats
    (a dict of RenderStats), require, after, band_seconds, ...
    """

    def __init__(self, message):
        super().__init__(message)
        self.state = state_name(message.state)

    @property
    def finished(self):
        """True once the job succeeded, failed or was cancelled."""
        return self.state in FINISHED_STATES

    def as_dict(self):
        d = super().as_dict()
        d["state"] = self.state
        return d

    def _summary(self):
        return {"job_id": self.job_id, "state": self.state, "bands_done": self.bands_done,
                "bands_total": self.bands_total, "frames_done": self.frames_done,
                "frames_total": self.frames_total}


class WorkerInfo(Record):
    """A connected worker (message WorkerInfo): worker_id, name (host:pid),
    threads, state ("idle", "busy", "draining", "disabled"), job_id, frame
    and band of the band in hand, bands_done, seconds_since_seen, tags."""


class Event(Record):
    """A line of a job's history (message JobEvent): seq (the cursor),
    unix_seconds, frame and band (-1: none), text."""


class LogLine(Record):
    """A line a worker logged for a band (message BandLogLine): seq, frame,
    band, lease_id, worker_id, text."""
