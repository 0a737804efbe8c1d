"""Scenes for submission: the native JSON format as `locus.v1.Scene`.

The native scene format (docs/scene-format.md) *is* proto/scene.proto
written as JSON: the C++ loader reads it with protobuf's JSON parser
(unknown fields and repeated keys refused) and then converts and validates
the message (scene_from_proto). Python's protobuf JSON parser reads the same
text into the same message, so this module needs no loader of its own; the
coordinator runs the same conversion and validation on every submitted
scene and answers INVALID_ARGUMENT with the JSON path of each problem.

Two things the C++ client does are not done here:
- NFF files (.nff): their parser is C++ only; submit them with `locus submit`.
- OBJ meshes (`"mesh": {"obj": "file.obj"}`): a submitted scene carries its
  meshes inline, and the CLI reads OBJ files with tinyobjloader. A scene
  file naming one is refused here; inline the mesh, or submit with the CLI.
  (A Scene message built by hand is sent as it is: a farm started with
  --mesh-root accepts `obj` paths inside that directory.)
"""

import json
import os
import re

import grpc
from google.protobuf import json_format

from .errors import FarmError
from .proto import scene_pb2

Scene = scene_pb2.Scene


def _invalid(message):
    return FarmError(grpc.StatusCode.INVALID_ARGUMENT, message)


def _refuse_obj_files(scene, name):
    for i, obj in enumerate(scene.objects):
        if obj.WhichOneof("shape") == "mesh" and obj.mesh.obj:
            raise _invalid(
                f"{name}: objects[{i}].mesh.obj: '{obj.mesh.obj}': the Python client sends "
                "meshes inline and does not read OBJ files; give the mesh's positions, normals "
                "and indices in the scene, or submit it with `locus submit`")


_UNKNOWN_FIELD = re.compile(r'Message type "[^"]*" has no field named "([^"]*)" at "([^"]*)"\.'
                            r'\s*Available Fields\(except extensions\): "\[([^\]]*)\]"')
_AT_PATH = re.compile(r'^(.*?)\s+at "?(Scene[^"\s]*?)"?\.*$', re.S)


def _json_path(proto_path):
    # "Scene.objects[0].sphere" -> "objects[0].sphere"; "Scene" -> "".
    return proto_path[len("Scene"):].lstrip(".")


def _reword(message):
    """protobuf's JSON error in the C++ loader's form: the JSON path first."""
    message = re.sub(r"(Failed to parse \w+ field: )+", "", message).strip()
    unknown = _UNKNOWN_FIELD.search(message)
    if unknown:
        field, path, fields = unknown.groups()
        where = ".".join(p for p in (_json_path(path), field) if p)
        names = ", ".join(f.strip(" '") for f in fields.split(","))
        return f"{where}: unknown field (the fields here: {names}; docs/scene-format.md)"
    at = _AT_PATH.match(message)
    if at and _json_path(at.group(2)):
        return f"{_json_path(at.group(2))}: {at.group(1)}"
    return message


def _check_spellings(value, path):
    # base_radius and baseRadius are one field (protobuf accepts both
    # spellings); giving both is an error, as in the C++ loader.
    if isinstance(value, dict):
        seen = {}
        for key, item in value.items():
            field = re.sub(r"[A-Z]", lambda m: "_" + m.group(0).lower(), key)
            if field in seen:
                raise _invalid(f"{path or 'the top level'}: \"{seen[field]}\" and \"{key}\" are "
                               "the same field, given twice")
            seen[field] = key
            _check_spellings(item, f"{path}.{key}" if path else key)
    elif isinstance(value, list):
        for i, item in enumerate(value):
            _check_spellings(item, f"{path}[{i}]")


def scene_from_dict(scene, name="scene"):
    """A `locus.v1.Scene` from a dict in the native JSON format.

    `scene` is what `json.load` gives for a scene file, e.g.
    {"camera": {"from": [0, 2, 8], "at": [0, 1, 0], "width": 320, "height": 240},
     "lights": [{"position": [-5, 8, 6]}], "materials": [{"color": [1, 0, 0]}],
     "objects": [{"sphere": {"center": [0, 1, 0], "radius": 1}}]}.
    Unknown fields are errors (FarmError INVALID_ARGUMENT, naming `name` and
    the field), as in the C++ loader. The values themselves are checked by
    the coordinator at submission.
    """
    if not isinstance(scene, dict):
        raise TypeError(f"scene_from_dict: expected a dict, got {type(scene).__name__}")
    try:
        _check_spellings(scene, "")
    except FarmError as e:
        raise _invalid(f"{name}: {e}") from None
    message = Scene()
    try:
        json_format.ParseDict(scene, message, ignore_unknown_fields=False)
    except json_format.ParseError as e:
        raise _invalid(f"{name}: {_reword(str(e))}") from None
    _refuse_obj_files(message, name)
    return message


def load_scene(path):
    """The `locus.v1.Scene` of a scene file in the native JSON format (.json).

    Raises FarmError: INVALID_ARGUMENT for a file that is not a JSON scene
    (a syntax error with its line and column, an unknown field, a key given
    twice, an NFF file, an OBJ mesh), FAILED_PRECONDITION for one that
    cannot be read.
    """
    path = os.fspath(path)
    ext = os.path.splitext(path)[1].lower()
    if ext == ".nff":
        raise _invalid(f"{path}: NFF scenes are read by the C++ loader only; submit them with "
                       "`locus submit`, or write the scene in the native JSON format "
                       "(docs/scene-format.md)")
    if ext != ".json":
        raise _invalid(f"{path}: unknown scene format '{ext or 'no extension'}' (expected a "
                       ".json scene, docs/scene-format.md)")
    try:
        with open(path, encoding="utf-8") as f:
            text = f.read()
    except (OSError, UnicodeDecodeError) as e:
        raise FarmError(grpc.StatusCode.FAILED_PRECONDITION,
                        f"{path}: cannot read the scene file ({e})") from None
    try:
        data = json.loads(text, object_pairs_hook=_no_repeated_keys,
                          parse_constant=_no_bare_constants)
    except json.JSONDecodeError as e:
        raise _invalid(f"{path}:{e.lineno}:{e.colno}: {e.msg}") from None
    except ValueError as e:
        raise _invalid(f"{path}: {e}") from None
    if not isinstance(data, dict):
        raise _invalid(f"{path}:1:1: a scene file must hold one JSON object {{ ... }}")
    return scene_from_dict(data, name=path)


def _no_repeated_keys(pairs):
    # protobuf would keep the last of two equal keys silently (as the C++
    # loader's syntax check says, docs/scene-format.md).
    seen = {}
    for key, value in pairs:
        if key in seen:
            raise ValueError(f"the key \"{key}\" is given twice in one object")
        seen[key] = value
    return seen


def _no_bare_constants(word):
    # RFC 8259 has no NaN or Infinity literals (strings "NaN" are fine).
    raise ValueError(f"{word} is not JSON; write it as a string, \"{word}\"")
