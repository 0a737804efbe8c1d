"""locus: a Python client of the Locus render farm (docs/python.md).

    import locus
    with locus.Farm("127.0.0.1:7000", token_file="~/.locus-token") as farm:
        job = farm.submit("scenes/anim/spinning_mirror.json", frames=(1, 12),
                          out="spin_####.png", size=(320, 240))
        status = farm.wait(job)
        paths = farm.fetch(job, "out/")

Farm talks to a coordinator's ClientService (proto/locus.proto); every
failure is a FarmError carrying the gRPC status code. Scenes are
`locus.Scene` messages (proto/scene.proto), which is what the native JSON
scene files are: load_scene() reads one, scene_from_dict() builds one.
"""

try:
    from .proto import locus_pb2, locus_pb2_grpc, scene_pb2
except ImportError as e:  # pragma: no cover - a broken setup, said plainly
    if getattr(e, "name", "") in ("grpc", "google", "google.protobuf"):
        raise ImportError(f"locus needs {e.name}: apt-get install python3-grpcio "
                          "python3-protobuf (deploy/local/install-deps.sh)") from e
    raise ImportError("locus: the generated stubs (locus/proto/*_pb2.py) are missing: build "
                      "the project and use PYTHONPATH=BUILD/python, where the build makes them "
                      f"({e})") from e

from .errors import FarmError
from .farm import Farm, check_plain_file_name, is_loopback
from .records import FINISHED_STATES, Event, JobStatus, LogLine, WorkerInfo, state_name
from .scenes import Scene, load_scene, scene_from_dict

__all__ = [
    "Farm", "FarmError", "Scene", "load_scene", "scene_from_dict", "JobStatus", "WorkerInfo",
    "Event", "LogLine", "FINISHED_STATES", "state_name", "is_loopback", "check_plain_file_name",
    "locus_pb2", "locus_pb2_grpc", "scene_pb2",
]
