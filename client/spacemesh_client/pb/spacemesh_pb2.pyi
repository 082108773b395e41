from google.protobuf.internal import containers as _containers
from google.protobuf import descriptor as _descriptor
from google.protobuf import message as _message
from collections.abc import Iterable as _Iterable, Mapping as _Mapping
from typing import ClassVar as _ClassVar, Optional as _Optional, Union as _Union

DESCRIPTOR: _descriptor.FileDescriptor

class PointCloudFile(_message.Message):
    __slots__ = ("data", "filename")
    DATA_FIELD_NUMBER: _ClassVar[int]
    FILENAME_FIELD_NUMBER: _ClassVar[int]
    data: bytes
    filename: str
    def __init__(self, data: _Optional[bytes] = ..., filename: _Optional[str] = ...) -> None: ...

class Points(_message.Message):
    __slots__ = ("xyz", "normals")
    XYZ_FIELD_NUMBER: _ClassVar[int]
    NORMALS_FIELD_NUMBER: _ClassVar[int]
    xyz: _containers.RepeatedScalarFieldContainer[float]
    normals: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, xyz: _Optional[_Iterable[float]] = ..., normals: _Optional[_Iterable[float]] = ...) -> None: ...

class GenerateRequest(_message.Message):
    __slots__ = ("file", "points", "format", "seed", "steps")
    FILE_FIELD_NUMBER: _ClassVar[int]
    POINTS_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    STEPS_FIELD_NUMBER: _ClassVar[int]
    file: PointCloudFile
    points: Points
    format: str
    seed: int
    steps: int
    def __init__(self, file: _Optional[_Union[PointCloudFile, _Mapping]] = ..., points: _Optional[_Union[Points, _Mapping]] = ..., format: _Optional[str] = ..., seed: _Optional[int] = ..., steps: _Optional[int] = ...) -> None: ...

class MeshStats(_message.Message):
    __slots__ = ("vertices", "faces", "edges", "face_degrees", "manifold", "closed", "oriented", "components", "genus")
    class FaceDegreesEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: int
        value: int
        def __init__(self, key: _Optional[int] = ..., value: _Optional[int] = ...) -> None: ...
    VERTICES_FIELD_NUMBER: _ClassVar[int]
    FACES_FIELD_NUMBER: _ClassVar[int]
    EDGES_FIELD_NUMBER: _ClassVar[int]
    FACE_DEGREES_FIELD_NUMBER: _ClassVar[int]
    MANIFOLD_FIELD_NUMBER: _ClassVar[int]
    CLOSED_FIELD_NUMBER: _ClassVar[int]
    ORIENTED_FIELD_NUMBER: _ClassVar[int]
    COMPONENTS_FIELD_NUMBER: _ClassVar[int]
    GENUS_FIELD_NUMBER: _ClassVar[int]
    vertices: int
    faces: int
    edges: int
    face_degrees: _containers.ScalarMap[int, int]
    manifold: bool
    closed: bool
    oriented: bool
    components: int
    genus: int
    def __init__(self, vertices: _Optional[int] = ..., faces: _Optional[int] = ..., edges: _Optional[int] = ..., face_degrees: _Optional[_Mapping[int, int]] = ..., manifold: _Optional[bool] = ..., closed: _Optional[bool] = ..., oriented: _Optional[bool] = ..., components: _Optional[int] = ..., genus: _Optional[int] = ...) -> None: ...

class MeshReply(_message.Message):
    __slots__ = ("mesh", "format", "media_type", "stats", "seed", "steps", "sampler", "model_name", "model_version", "timings", "batch_size")
    class TimingsEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: float
        def __init__(self, key: _Optional[str] = ..., value: _Optional[float] = ...) -> None: ...
    MESH_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    MEDIA_TYPE_FIELD_NUMBER: _ClassVar[int]
    STATS_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    STEPS_FIELD_NUMBER: _ClassVar[int]
    SAMPLER_FIELD_NUMBER: _ClassVar[int]
    MODEL_NAME_FIELD_NUMBER: _ClassVar[int]
    MODEL_VERSION_FIELD_NUMBER: _ClassVar[int]
    TIMINGS_FIELD_NUMBER: _ClassVar[int]
    BATCH_SIZE_FIELD_NUMBER: _ClassVar[int]
    mesh: bytes
    format: str
    media_type: str
    stats: MeshStats
    seed: int
    steps: int
    sampler: str
    model_name: str
    model_version: str
    timings: _containers.ScalarMap[str, float]
    batch_size: int
    def __init__(self, mesh: _Optional[bytes] = ..., format: _Optional[str] = ..., media_type: _Optional[str] = ..., stats: _Optional[_Union[MeshStats, _Mapping]] = ..., seed: _Optional[int] = ..., steps: _Optional[int] = ..., sampler: _Optional[str] = ..., model_name: _Optional[str] = ..., model_version: _Optional[str] = ..., timings: _Optional[_Mapping[str, float]] = ..., batch_size: _Optional[int] = ...) -> None: ...

class Progress(_message.Message):
    __slots__ = ("step", "total")
    STEP_FIELD_NUMBER: _ClassVar[int]
    TOTAL_FIELD_NUMBER: _ClassVar[int]
    step: int
    total: int
    def __init__(self, step: _Optional[int] = ..., total: _Optional[int] = ...) -> None: ...

class GenerateEvent(_message.Message):
    __slots__ = ("progress", "mesh")
    PROGRESS_FIELD_NUMBER: _ClassVar[int]
    MESH_FIELD_NUMBER: _ClassVar[int]
    progress: Progress
    mesh: MeshReply
    def __init__(self, progress: _Optional[_Union[Progress, _Mapping]] = ..., mesh: _Optional[_Union[MeshReply, _Mapping]] = ...) -> None: ...

class RepairRequest(_message.Message):
    __slots__ = ("mesh", "filename", "faces", "format", "seed", "steps")
    MESH_FIELD_NUMBER: _ClassVar[int]
    FILENAME_FIELD_NUMBER: _ClassVar[int]
    FACES_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    STEPS_FIELD_NUMBER: _ClassVar[int]
    mesh: bytes
    filename: str
    faces: _containers.RepeatedScalarFieldContainer[int]
    format: str
    seed: int
    steps: int
    def __init__(self, mesh: _Optional[bytes] = ..., filename: _Optional[str] = ..., faces: _Optional[_Iterable[int]] = ..., format: _Optional[str] = ..., seed: _Optional[int] = ..., steps: _Optional[int] = ...) -> None: ...
