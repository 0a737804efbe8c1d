"""Farm: the ClientService of a Locus coordinator, from Python.

The same rules as the C++ client (client/farm_client.cpp,
proto/wire/rpc.cpp): every call has a deadline; the token goes as
`authorization: Bearer TOKEN` on every call; TLS when a CA is given,
plaintext only to a loopback address unless `insecure=True`; a submission
carries one request id, reused on every retry; a watch re-opens the
server's capped streams; fetched files are written atomically, and only
under plain file names.
"""

import ipaddress
import logging
import os
import stat
import time
import uuid

import grpc

from .errors import FarmError, from_rpc_error
from .proto import locus_pb2, locus_pb2_grpc, scene_pb2
from .records import Event, JobStatus, LogLine, WorkerInfo
from .scenes import load_scene, scene_from_dict

# Deadlines, in seconds, as in proto/wire/rpc.h (kShortCall, kDataCall).
SHORT_CALL = 10.0   # status, actions, lists
DATA_CALL = 120.0   # submit, fetch
# A watch asks the server for streams of at most this long (its own cap
# applies) and re-opens them; each has this plus SHORT_CALL as deadline.
WATCH_STREAM_SECONDS = 30
# How long a submission is retried (same request id), and how long a watch
# that lost a farm it had reached waits for it to come back (a restart).
SUBMIT_RETRY_FOR = 10.0
WATCH_RETRY_FOR = 60.0

DEFAULT_FARM = "127.0.0.1:7000"
MAX_MESSAGE_BYTES = 64 << 20   # farm::kMaxMessageBytes, on every channel
MAX_EVENTS_PER_CALL = 10000    # farm::kMaxEventsPerCall: a shorter page is the last
_MAX_TOKEN_BYTES = 4096
_TRANSIENT = (grpc.StatusCode.UNAVAILABLE, grpc.StatusCode.DEADLINE_EXCEEDED)
_CHANNEL_OPTIONS = [
    ("grpc.max_receive_message_length", MAX_MESSAGE_BYTES),
    ("grpc.max_send_message_length", MAX_MESSAGE_BYTES),
    # Reconnect quickly after a coordinator restart rather than backing off
    # for minutes.
    ("grpc.max_reconnect_backoff_ms", 2000),
    ("grpc.initial_reconnect_backoff_ms", 200),
    ("grpc.min_reconnect_backoff_ms", 200),
]

_log = logging.getLogger("locus")
_C = grpc.StatusCode


def is_loopback(address):
    """True for 127.0.0.0/8, ::1, localhost and unix sockets (rpc::is_loopback):
    the addresses where plaintext never leaves the host."""
    a = address
    if a.startswith("unix:"):
        return True
    for scheme in ("ipv4:", "ipv6:", "dns:///", "dns:"):
        if a.startswith(scheme):
            a = a[len(scheme):]
            break
    if a.startswith("["):
        close = a.find("]")
        if close < 0:
            return False
        host = a[1:close]
    else:
        colon = a.rfind(":")
        host = a if colon < 0 else a[:colon]
    if host in ("localhost", "::1"):
        return True
    try:
        ip = ipaddress.IPv4Address(host)
    except ValueError:
        return False
    return ip.is_loopback


def check_plain_file_name(name, what):
    """Refuses (FarmError INVALID_ARGUMENT) a name that is not a plain file
    name: empty, ".", "..", with a "/" or a control character
    (farm::check_plain_file_name). A coordinator cannot make a client write
    outside the directory it was given."""
    if (not name or name in (".", "..") or "/" in name
            or any(ord(c) < 0x20 or ord(c) == 0x7F for c in name)):
        raise FarmError(_C.INVALID_ARGUMENT, f"{what}: '{name}' is not a plain file name")


def _printable(token):
    return all(0x21 <= ord(c) <= 0x7E for c in token)


def _bad_token(where):
    return FarmError(_C.INVALID_ARGUMENT,
                     f"{where}: a token is 1..{_MAX_TOKEN_BYTES} visible ASCII characters "
                     "without spaces")


def _read_token_file(path):
    # farm::load_token: the first token line; blank lines and # comments
    # skipped, white space trimmed.
    path = os.path.expanduser(path)
    try:
        with open(path, encoding="ascii", errors="replace") as f:
            lines = f.read().splitlines()
    except OSError:
        raise FarmError(_C.FAILED_PRECONDITION,
                        f"token_file {path}: cannot read the file") from None
    tokens = []
    for number, line in enumerate(lines, 1):
        t = line.strip(" \t\r\n")
        if not t or t.startswith("#"):
            continue
        if not _printable(t) or len(t) > _MAX_TOKEN_BYTES:
            raise _bad_token(f"token_file {path}:{number}")
        tokens.append(t)
    if not tokens:
        raise FarmError(_C.INVALID_ARGUMENT, f"token_file {path}: holds no token (one per "
                        "line; # starts a comment)")
    try:
        if os.stat(path).st_mode & (stat.S_IRWXG | stat.S_IRWXO):
            _log.warning("token_file %s: readable by other users; chmod 600 it", path)
    except OSError:
        pass
    return tokens[0]


def _load_token(token, token_file):
    if token is not None:
        where, t = "token", token.strip(" \t\r\n")
    elif token_file is not None:
        return _read_token_file(os.fspath(token_file))
    else:
        where, t = "LOCUS_TOKEN", os.environ.get("LOCUS_TOKEN", "").strip(" \t\r\n")
    if not _printable(t) or len(t) > _MAX_TOKEN_BYTES:
        raise _bad_token(where)
    return t


def _read_pem(path, what):
    path = os.path.expanduser(os.fspath(path))
    try:
        with open(path, "rb") as f:
            pem = f.read()
    except OSError:
        raise FarmError(_C.FAILED_PRECONDITION, f"{what} {path}: cannot read the file") from None
    if b"-----BEGIN " not in pem:
        raise FarmError(_C.INVALID_ARGUMENT, f"{what} {path}: not a PEM file (no -----BEGIN line)")
    return pem


def _frame_range(frames):
    if isinstance(frames, int):
        return frames, frames
    try:
        first, last = frames
    except (TypeError, ValueError):
        raise TypeError(f"frames: expected (first, last) or one frame number, got {frames!r}") \
            from None
    return int(first), int(last)


def _size(size):
    if isinstance(size, str):
        w, sep, h = size.partition("x")
        if not sep or not w.isdigit() or not h.isdigit():
            raise FarmError(_C.INVALID_ARGUMENT,
                            f"size: expected WIDTHxHEIGHT such as 640x480, got '{size}'")
        return int(w), int(h)
    try:
        w, h = size
    except (TypeError, ValueError):
        raise TypeError(f"size: expected (width, height) or 'WxH', got {size!r}") from None
    return int(w), int(h)


def _as_scene(scene):
    """The Scene message to send and its name for messages."""
    if isinstance(scene, scene_pb2.Scene):
        copy = scene_pb2.Scene()
        copy.CopyFrom(scene)
        return copy, "scene"
    if isinstance(scene, dict):
        return scene_from_dict(scene), "scene"
    if isinstance(scene, (str, os.PathLike)):
        return load_scene(scene), os.fspath(scene)
    raise TypeError("scene: expected a locus.v1.Scene, a dict in the native JSON format or "
                    f"the path of a .json scene file, got {type(scene).__name__}")


class Farm:
    """A coordinator's ClientService.

    Farm(address, token=None, token_file=None, ca=None, insecure=False,
         cert=None, key=None)

    address: HOST:PORT (default $LOCUS_FARM, then 127.0.0.1:7000).
    token: a client token; else the first token line of `token_file`; else
        $LOCUS_TOKEN; none at all is fine on a farm without tokens.
    ca: the PEM file of the CA that signed the coordinator's certificate:
        the calls go over TLS, verified against it (the certificate must
        name the address dialled). cert, key: a client certificate and its
        key, for mutual TLS (optional for clients).
    insecure: without `ca`, plaintext is used only for loopback addresses
        (127.0.0.0/8, ::1, localhost); True allows it anywhere (a trusted
        network only: the token would cross it in clear text).

    Every method raises FarmError on failure. A Farm is a context manager;
    close() closes its channel.
    """

    def __init__(self, address=None, token=None, token_file=None, ca=None, insecure=False,
                 cert=None, key=None):
        self.address = address or os.environ.get("LOCUS_FARM") or DEFAULT_FARM
        self._peer = f"farm at {self.address}"
        token = _load_token(token, token_file)
        self._metadata = (("authorization", "Bearer " + token),) if token else ()
        if (cert is None) != (key is None):
            raise FarmError(_C.INVALID_ARGUMENT,
                            "cert and key go together (a client certificate and its key)")
        if ca is not None or cert is not None:
            credentials = grpc.ssl_channel_credentials(
                root_certificates=_read_pem(ca, "ca") if ca is not None else None,
                private_key=_read_pem(key, "key") if key is not None else None,
                certificate_chain=_read_pem(cert, "cert") if cert is not None else None)
            self._channel = grpc.secure_channel(self.address, credentials, _CHANNEL_OPTIONS)
        elif insecure or is_loopback(self.address):
            self._channel = grpc.insecure_channel(self.address, _CHANNEL_OPTIONS)
        else:
            raise FarmError(_C.FAILED_PRECONDITION,
                            f"{self._peer}: give ca='CA.pem' to reach it over TLS, or "
                            "insecure=True for plaintext on a trusted network (plaintext is the "
                            "default only on loopback addresses)")
        self._stub = locus_pb2_grpc.ClientServiceStub(self._channel)

    def close(self):
        """Closes the channel; the Farm makes no more calls."""
        self._channel.close()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __repr__(self):
        return f"Farm({self.address!r})"

    # ---- plumbing

    def _call(self, method, request, timeout=SHORT_CALL):
        try:
            return method(request, timeout=timeout, metadata=self._metadata)
        except grpc.RpcError as e:
            raise from_rpc_error(e, self.address) from None

    def _action(self, method, request):
        return JobStatus(self._call(method, request).status)

    # ---- jobs

    def submit(self, scene, frames=(1, 1), out="frame_####.png", size=None, bands=0,
               priority=50, after=(), require=(), method=None, spp=None, aa=None, orbit=0.0,
               request_id=None, boxes=None, tess_tol=None, frame_order=None,
               band_timeout=None, scene_name=None, movie=None, fps=None, notify_url=None,
               cost_map=None):
        """Submits a job; returns its id ("j0007").

        scene: a locus.v1.Scene (locus.Scene), the path of a scene file in
            the native JSON format (scenes/*.json), or such a scene as a dict.
        frames: (first, last), both included, or one frame number.
        out: the output pattern; `####` becomes the zero-padded frame number.
            Only its file name goes to the farm (the coordinator writes under
            its output root); fetch() downloads the files.
        size: (width, height) or "WxH"; None: the scene camera's.
        bands: bands per frame; 0: the coordinator chooses.
        priority: 0..100, higher first. after: job ids to wait for.
        require: worker tags the job's bands need.
        method: "local" (default) or "raytrace"; spp: raytrace's N x N
            samples; aa: local's sub-scanlines per row (0: point sampling);
            boxes: "none", "eye", "eye+shadow" (default); tess_tol: pixels.
        orbit: degrees the camera turns about `at` over the frames.
        frame_order: "in-order" (default) or "first-middle-last".
        band_timeout: seconds a band may stay leased (None: the farm's).
        movie: a movie of the frames once all are written, "shot.mp4"
            (H.264), ".webm" or ".gif" (frames PNG or TIFF), at `fps` (default
            24): the coordinator makes it as a job of its own after this one;
            job(id).movie_job names it, and fetch() of that job downloads it.
        notify_url: POSTed the job's final status as JSON when it ends (with
            a movie, when the movie is made); the farm's --notify-urls must
            allow it.
        cost_map: a pattern like `out` ("cost_####.png"; .png, .exr, .tif)
            for a cost map of each frame, written beside it: where the work
            went, per pixel (docs/cost-map.md). fetch(..., cost_maps=True)
            downloads them.
        request_id: the submission's idempotency key; default a fresh uuid4,
            sent again on every retry of this call, so the job is created
            once however many attempts reached the farm. A retry with the
            same id and a different job is ALREADY_EXISTS.

        Transient failures (UNAVAILABLE, DEADLINE_EXCEEDED) are retried for
        SUBMIT_RETRY_FOR seconds. The coordinator validates everything (the
        scene with the JSON path of each problem) before storing anything.
        """
        message, name = _as_scene(scene)
        first, last = _frame_range(frames)
        spec = locus_pb2.JobSpec(scene_name=scene_name or name, frame_first=first,
                                 frame_last=last, bands=bands,
                                 output=os.path.basename(os.fspath(out)),
                                 orbit_degrees=orbit, priority=priority,
                                 frame_order=frame_order or "", require=list(require),
                                 after=list(after),
                                 movie=os.path.basename(os.fspath(movie)) if movie else "",
                                 fps=fps or 0, notify_url=notify_url or "",
                                 cost_map=os.path.basename(os.fspath(cost_map)) if cost_map
                                 else "")
        if size is not None:
            width, height = _size(size)
            # As the CLI does: the scene's camera gets the size too.
            if message.HasField("camera"):
                message.camera.width, message.camera.height = width, height
        else:
            width, height = message.camera.width, message.camera.height
        spec.width, spec.height = width, height
        spec.scene.CopyFrom(message)
        spec.render.method = method or ""
        spec.render.boxes = boxes or ""
        spec.render.spp = spp or 0
        if aa is not None:
            spec.render.aa = aa
        if tess_tol is not None:
            spec.render.tess_tol = tess_tol
        if band_timeout is not None:
            spec.band_timeout_ms = int(round(band_timeout * 1000))
        request = locus_pb2.SubmitJobRequest(spec=spec, request_id=request_id or uuid.uuid4().hex)
        give_up = time.monotonic() + SUBMIT_RETRY_FOR
        backoff = 0.25
        while True:
            try:
                return self._call(self._stub.SubmitJob, request, DATA_CALL).job_id
            except FarmError as e:
                if e.code not in _TRANSIENT or time.monotonic() + backoff > give_up:
                    raise
            time.sleep(backoff)
            backoff = min(backoff * 2, 1.0)

    def job(self, job_id):
        """The job's JobStatus (NOT_FOUND for an unknown id)."""
        return JobStatus(self._call(self._stub.GetJob, locus_pb2.GetJobRequest(job_id=job_id)))

    def jobs(self):
        """Every job the coordinator holds (a user's own with --private-jobs)."""
        response = self._call(self._stub.ListJobs, locus_pb2.ListJobsRequest())
        return [JobStatus(j) for j in response.jobs]

    def watch(self, job_id):
        """Yields the job's JobStatus at once and on every change, until it
        has succeeded, failed or been cancelled (the last one yielded).

        The server ends each stream after at most WATCH_STREAM_SECONDS; the
        watch re-opens it. A farm that goes away after it was reached (a
        coordinator restarting) is waited for WATCH_RETRY_FOR seconds; one
        never reached is an error at once.
        """
        give_up = time.monotonic() + WATCH_RETRY_FOR
        backoff = 0.25
        reached = False
        while True:
            request = locus_pb2.WatchJobRequest(job_id=job_id, max_seconds=WATCH_STREAM_SECONDS)
            call = self._stub.WatchJob(request, timeout=WATCH_STREAM_SECONDS + SHORT_CALL,
                                       metadata=self._metadata)
            last = None
            try:
                for status in call:
                    last = JobStatus(status)
                    yield last
            except grpc.RpcError as e:
                error = from_rpc_error(e, self.address)
                reached = reached or last is not None
                if (not reached or error.code not in _TRANSIENT
                        or time.monotonic() + backoff > give_up):
                    raise error from None
                time.sleep(backoff)
                backoff = min(backoff * 2, 1.0)
                continue
            finally:
                call.cancel()
            if last is not None and last.finished:
                return
            reached = True
            give_up = time.monotonic() + WATCH_RETRY_FOR
            backoff = 0.25

    def wait(self, job_id):
        """Follows the job to its end (watch()); returns its last JobStatus."""
        last = None
        for last in self.watch(job_id):
            pass
        return last

    def cancel(self, job_id):
        """Cancels the job (its owner or an admin); its JobStatus after."""
        return self._action(self._stub.CancelJob, locus_pb2.CancelJobRequest(job_id=job_id))

    def pause(self, job_id):
        """No new leases for the job; bands in flight finish and are kept."""
        return self._action(self._stub.PauseJob, locus_pb2.JobActionRequest(job_id=job_id))

    def resume(self, job_id):
        """A paused job queued or running again."""
        return self._action(self._stub.ResumeJob, locus_pb2.JobActionRequest(job_id=job_id))

    def priority(self, job_id, priority, preempt=False):
        """Sets the job's priority (0..100; effective at the next lease).
        preempt: running bands of jobs of lower priority are handed back now."""
        return self._action(self._stub.SetPriority, locus_pb2.SetPriorityRequest(
            job_id=job_id, priority=priority, preempt=preempt))

    def retry(self, job_id):
        """A failed or cancelled job back in the queue: the bands it lacks,
        with fresh attempts."""
        return self._action(self._stub.RetryJob, locus_pb2.JobActionRequest(job_id=job_id))

    def requeue(self, job_id, first=None, last=None):
        """The written frames in [first, last] (None: the job's own bounds)
        render again; each file is replaced when its new frame is complete."""
        request = locus_pb2.RequeueJobRequest(job_id=job_id)
        if first is not None:
            request.frame_first = first
        if last is not None:
            request.frame_last = last
        return self._action(self._stub.RequeueJob, request)

    def delete(self, job_id, outputs=False):
        """Deletes a finished job (record, history, band files; with
        `outputs` its frames too). Returns its last JobStatus."""
        return self._action(self._stub.DeleteJob,
                            locus_pb2.DeleteJobRequest(job_id=job_id, outputs=outputs))

    def events(self, job_id, after=0):
        """The job's history after cursor `after` (all of it from 0), oldest
        first, as Event records (seq, unix_seconds, frame, band, text)."""
        out = []
        while True:
            response = self._call(self._stub.ListEvents,
                                  locus_pb2.ListEventsRequest(job_id=job_id, after_seq=after))
            out.extend(Event(e) for e in response.events)
            if response.events:
                after = response.events[-1].seq
            if len(response.events) < MAX_EVENTS_PER_CALL:
                return out

    def logs(self, job_id, frame=None, band=None, after=0):
        """What workers logged for the job's bands (of one frame and band
        when given) after cursor `after`, as LogLine records."""
        out = []
        while True:
            request = locus_pb2.ListLogsRequest(job_id=job_id, after_seq=after)
            if frame is not None:
                request.frame = frame
            if band is not None:
                request.band = band
            response = self._call(self._stub.ListLogs, request)
            out.extend(LogLine(line) for line in response.lines)
            if response.lines:
                after = response.lines[-1].seq
            if len(response.lines) < MAX_EVENTS_PER_CALL:
                return out

    def fetch(self, job_id, directory, frames=None, cost_maps=False):
        """Downloads the job's written frames (`frames`: those frame numbers;
        None: every frame written so far) into `directory`, created if
        needed, under the file names the farm gives (shot_0007.png). Each
        file is written to NAME.partial and renamed into place. Returns the
        paths written, in the order received. `cost_maps`: the frames' cost
        maps instead (a job submitted with cost_map; FAILED_PRECONDITION
        for one without).

        A name that is not a plain file name is refused (INVALID_ARGUMENT)
        before anything is written; a frame not written yet is an error of
        the farm's (FAILED_PRECONDITION).
        """
        directory = os.fspath(directory)
        request = locus_pb2.FetchResultsRequest(job_id=job_id, frames=list(frames or ()),
                                                cost_maps=cost_maps)
        call = self._stub.FetchResults(request, timeout=DATA_CALL, metadata=self._metadata)
        written = []
        out = tmp = path = None
        expected = 0
        try:
            for chunk in call:
                if chunk.offset == 0:
                    # The name comes from the coordinator: it must not lead elsewhere.
                    check_plain_file_name(chunk.file_name, f"the {self._peer} sent a file")
                    if out is not None:
                        out.close()
                        os.remove(tmp)
                    os.makedirs(directory, exist_ok=True)
                    path = os.path.join(directory, chunk.file_name)
                    tmp = path + ".partial"
                    out = open(tmp, "wb")
                    expected = 0
                if out is None or chunk.offset != expected:
                    raise FarmError(_C.INTERNAL, f"the {self._peer}: frame {chunk.frame} "
                                    "arrived out of order")
                out.write(chunk.data)
                expected += len(chunk.data)
                if chunk.last:
                    out.close()
                    out = None
                    os.replace(tmp, path)
                    tmp = None
                    written.append(path)
            if out is not None:
                raise FarmError(_C.INTERNAL, f"the {self._peer} ended the transfer of {path} "
                                "before its last chunk")
        except grpc.RpcError as e:
            raise from_rpc_error(e, self.address) from None
        except OSError as e:
            raise FarmError(_C.FAILED_PRECONDITION,
                            f"{path or directory}: cannot write ({e.strerror or e})") from None
        finally:
            call.cancel()
            if out is not None:
                out.close()
            if tmp is not None and os.path.exists(tmp):
                os.remove(tmp)
        return written

    # ---- workers

    def workers(self):
        """The connected workers, as WorkerInfo records."""
        response = self._call(self._stub.ListWorkers, locus_pb2.ListWorkersRequest())
        return [WorkerInfo(w) for w in response.workers]

    def drain(self, worker):
        """Admins: the worker (id or host:pid name) finishes its band and
        exits. Returns its name."""
        return self._worker_action(self._stub.DrainWorker, worker)

    def disable(self, worker):
        """Admins: the worker, by name, gets no band until enable()."""
        return self._worker_action(self._stub.DisableWorker, worker)

    def enable(self, worker):
        """Admins: a disabled worker takes bands again."""
        return self._worker_action(self._stub.EnableWorker, worker)

    def _worker_action(self, method, worker):
        return self._call(method, locus_pb2.WorkerActionRequest(worker=worker)).worker_name
