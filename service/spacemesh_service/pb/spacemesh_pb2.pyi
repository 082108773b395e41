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
    __slots__ = ("file", "points", "format", "seed", "steps", "sampler", "start", "start_time", "target_vertices", "samples", "raw", "tolerance", "surface", "face_type", "stages")
    FILE_FIELD_NUMBER: _ClassVar[int]
    POINTS_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    STEPS_FIELD_NUMBER: _ClassVar[int]
    SAMPLER_FIELD_NUMBER: _ClassVar[int]
    START_FIELD_NUMBER: _ClassVar[int]
    START_TIME_FIELD_NUMBER: _ClassVar[int]
    TARGET_VERTICES_FIELD_NUMBER: _ClassVar[int]
    SAMPLES_FIELD_NUMBER: _ClassVar[int]
    RAW_FIELD_NUMBER: _ClassVar[int]
    TOLERANCE_FIELD_NUMBER: _ClassVar[int]
    SURFACE_FIELD_NUMBER: _ClassVar[int]
    FACE_TYPE_FIELD_NUMBER: _ClassVar[int]
    STAGES_FIELD_NUMBER: _ClassVar[int]
    file: PointCloudFile
    points: Points
    format: str
    seed: int
    steps: int
    sampler: str
    start: str
    start_time: float
    target_vertices: int
    samples: int
    raw: bool
    tolerance: float
    surface: str
    face_type: str
    stages: bool
    def __init__(self, file: _Optional[_Union[PointCloudFile, _Mapping]] = ..., points: _Optional[_Union[Points, _Mapping]] = ..., format: _Optional[str] = ..., seed: _Optional[int] = ..., steps: _Optional[int] = ..., sampler: _Optional[str] = ..., start: _Optional[str] = ..., start_time: _Optional[float] = ..., target_vertices: _Optional[int] = ..., samples: _Optional[int] = ..., raw: _Optional[bool] = ..., tolerance: _Optional[float] = ..., surface: _Optional[str] = ..., face_type: _Optional[str] = ..., stages: _Optional[bool] = ...) -> None: ...

class FitReport(_message.Message):
    __slots__ = ("points_to_mesh_mean", "points_to_mesh_p95", "mesh_to_points_mean", "mesh_to_points_p95", "points_to_mesh_mean_rel", "points_to_mesh_p95_rel", "mesh_to_points_mean_rel", "mesh_to_points_p95_rel", "coverage", "components", "self_intersections", "diagonal", "n_points", "pieces", "genus", "boundary_loops", "tolerance", "tolerance_met", "points_pieces", "points_outliers", "points_noise", "open_surface", "unsupported_area", "face_planarity")
    POINTS_TO_MESH_MEAN_FIELD_NUMBER: _ClassVar[int]
    POINTS_TO_MESH_P95_FIELD_NUMBER: _ClassVar[int]
    MESH_TO_POINTS_MEAN_FIELD_NUMBER: _ClassVar[int]
    MESH_TO_POINTS_P95_FIELD_NUMBER: _ClassVar[int]
    POINTS_TO_MESH_MEAN_REL_FIELD_NUMBER: _ClassVar[int]
    POINTS_TO_MESH_P95_REL_FIELD_NUMBER: _ClassVar[int]
    MESH_TO_POINTS_MEAN_REL_FIELD_NUMBER: _ClassVar[int]
    MESH_TO_POINTS_P95_REL_FIELD_NUMBER: _ClassVar[int]
    COVERAGE_FIELD_NUMBER: _ClassVar[int]
    COMPONENTS_FIELD_NUMBER: _ClassVar[int]
    SELF_INTERSECTIONS_FIELD_NUMBER: _ClassVar[int]
    DIAGONAL_FIELD_NUMBER: _ClassVar[int]
    N_POINTS_FIELD_NUMBER: _ClassVar[int]
    PIECES_FIELD_NUMBER: _ClassVar[int]
    GENUS_FIELD_NUMBER: _ClassVar[int]
    BOUNDARY_LOOPS_FIELD_NUMBER: _ClassVar[int]
    TOLERANCE_FIELD_NUMBER: _ClassVar[int]
    TOLERANCE_MET_FIELD_NUMBER: _ClassVar[int]
    POINTS_PIECES_FIELD_NUMBER: _ClassVar[int]
    POINTS_OUTLIERS_FIELD_NUMBER: _ClassVar[int]
    POINTS_NOISE_FIELD_NUMBER: _ClassVar[int]
    OPEN_SURFACE_FIELD_NUMBER: _ClassVar[int]
    UNSUPPORTED_AREA_FIELD_NUMBER: _ClassVar[int]
    FACE_PLANARITY_FIELD_NUMBER: _ClassVar[int]
    points_to_mesh_mean: float
    points_to_mesh_p95: float
    mesh_to_points_mean: float
    mesh_to_points_p95: float
    points_to_mesh_mean_rel: float
    points_to_mesh_p95_rel: float
    mesh_to_points_mean_rel: float
    mesh_to_points_p95_rel: float
    coverage: float
    components: int
    self_intersections: float
    diagonal: float
    n_points: int
    pieces: int
    genus: int
    boundary_loops: int
    tolerance: float
    tolerance_met: bool
    points_pieces: int
    points_outliers: float
    points_noise: float
    open_surface: bool
    unsupported_area: float
    face_planarity: float
    def __init__(self, points_to_mesh_mean: _Optional[float] = ..., points_to_mesh_p95: _Optional[float] = ..., mesh_to_points_mean: _Optional[float] = ..., mesh_to_points_p95: _Optional[float] = ..., points_to_mesh_mean_rel: _Optional[float] = ..., points_to_mesh_p95_rel: _Optional[float] = ..., mesh_to_points_mean_rel: _Optional[float] = ..., mesh_to_points_p95_rel: _Optional[float] = ..., coverage: _Optional[float] = ..., components: _Optional[int] = ..., self_intersections: _Optional[float] = ..., diagonal: _Optional[float] = ..., n_points: _Optional[int] = ..., pieces: _Optional[int] = ..., genus: _Optional[int] = ..., boundary_loops: _Optional[int] = ..., tolerance: _Optional[float] = ..., tolerance_met: _Optional[bool] = ..., points_pieces: _Optional[int] = ..., points_outliers: _Optional[float] = ..., points_noise: _Optional[float] = ..., open_surface: _Optional[bool] = ..., unsupported_area: _Optional[float] = ..., face_planarity: _Optional[float] = ...) -> None: ...

class SampleScore(_message.Message):
    __slots__ = ("seed", "score")
    SEED_FIELD_NUMBER: _ClassVar[int]
    SCORE_FIELD_NUMBER: _ClassVar[int]
    seed: int
    score: float
    def __init__(self, seed: _Optional[int] = ..., score: _Optional[float] = ...) -> None: ...

class MeshStats(_message.Message):
    __slots__ = ("vertices", "faces", "edges", "face_degrees", "manifold", "closed", "oriented", "components", "genus", "fit")
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
    FIT_FIELD_NUMBER: _ClassVar[int]
    vertices: int
    faces: int
    edges: int
    face_degrees: _containers.ScalarMap[int, int]
    manifold: bool
    closed: bool
    oriented: bool
    components: int
    genus: int
    fit: FitReport
    def __init__(self, vertices: _Optional[int] = ..., faces: _Optional[int] = ..., edges: _Optional[int] = ..., face_degrees: _Optional[_Mapping[int, int]] = ..., manifold: _Optional[bool] = ..., closed: _Optional[bool] = ..., oriented: _Optional[bool] = ..., components: _Optional[int] = ..., genus: _Optional[int] = ..., fit: _Optional[_Union[FitReport, _Mapping]] = ...) -> None: ...

class MeshReply(_message.Message):
    __slots__ = ("mesh", "format", "media_type", "stats", "seed", "steps", "sampler", "model_name", "model_version", "timings", "batch_size", "repair", "start", "start_time", "target_vertices", "samples", "raw", "sample_scores", "input_kind", "tolerance", "points_read", "points_used", "surface", "face_type")
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
    REPAIR_FIELD_NUMBER: _ClassVar[int]
    START_FIELD_NUMBER: _ClassVar[int]
    START_TIME_FIELD_NUMBER: _ClassVar[int]
    TARGET_VERTICES_FIELD_NUMBER: _ClassVar[int]
    SAMPLES_FIELD_NUMBER: _ClassVar[int]
    RAW_FIELD_NUMBER: _ClassVar[int]
    SAMPLE_SCORES_FIELD_NUMBER: _ClassVar[int]
    INPUT_KIND_FIELD_NUMBER: _ClassVar[int]
    TOLERANCE_FIELD_NUMBER: _ClassVar[int]
    POINTS_READ_FIELD_NUMBER: _ClassVar[int]
    POINTS_USED_FIELD_NUMBER: _ClassVar[int]
    SURFACE_FIELD_NUMBER: _ClassVar[int]
    FACE_TYPE_FIELD_NUMBER: _ClassVar[int]
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
    repair: RepairStats
    start: str
    start_time: float
    target_vertices: int
    samples: int
    raw: bool
    sample_scores: _containers.RepeatedCompositeFieldContainer[SampleScore]
    input_kind: str
    tolerance: float
    points_read: int
    points_used: int
    surface: str
    face_type: str
    def __init__(self, mesh: _Optional[bytes] = ..., format: _Optional[str] = ..., media_type: _Optional[str] = ..., stats: _Optional[_Union[MeshStats, _Mapping]] = ..., seed: _Optional[int] = ..., steps: _Optional[int] = ..., sampler: _Optional[str] = ..., model_name: _Optional[str] = ..., model_version: _Optional[str] = ..., timings: _Optional[_Mapping[str, float]] = ..., batch_size: _Optional[int] = ..., repair: _Optional[_Union[RepairStats, _Mapping]] = ..., start: _Optional[str] = ..., start_time: _Optional[float] = ..., target_vertices: _Optional[int] = ..., samples: _Optional[int] = ..., raw: _Optional[bool] = ..., sample_scores: _Optional[_Iterable[_Union[SampleScore, _Mapping]]] = ..., input_kind: _Optional[str] = ..., tolerance: _Optional[float] = ..., points_read: _Optional[int] = ..., points_used: _Optional[int] = ..., surface: _Optional[str] = ..., face_type: _Optional[str] = ...) -> None: ...

class RepairStats(_message.Message):
    __slots__ = ("requested_faces", "region_faces", "grown_faces", "removed_vertices", "boundary_vertices", "loops", "new_vertices", "new_faces", "new_face_degrees", "patch_faces", "patch_rings", "known_vertices", "tokens", "candidates", "fallback", "fill", "inpaint", "flipped_orientation", "welded_vertices", "region_share", "auto_region", "passes", "reversed_faces", "flipped_mesh", "samplings", "handles_added", "findings", "findings_total", "regions")
    class NewFaceDegreesEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: int
        value: int
        def __init__(self, key: _Optional[int] = ..., value: _Optional[int] = ...) -> None: ...
    class FillEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    class InpaintEntry(_message.Message):
        __slots__ = ("key", "value")
        KEY_FIELD_NUMBER: _ClassVar[int]
        VALUE_FIELD_NUMBER: _ClassVar[int]
        key: str
        value: int
        def __init__(self, key: _Optional[str] = ..., value: _Optional[int] = ...) -> None: ...
    REQUESTED_FACES_FIELD_NUMBER: _ClassVar[int]
    REGION_FACES_FIELD_NUMBER: _ClassVar[int]
    GROWN_FACES_FIELD_NUMBER: _ClassVar[int]
    REMOVED_VERTICES_FIELD_NUMBER: _ClassVar[int]
    BOUNDARY_VERTICES_FIELD_NUMBER: _ClassVar[int]
    LOOPS_FIELD_NUMBER: _ClassVar[int]
    NEW_VERTICES_FIELD_NUMBER: _ClassVar[int]
    NEW_FACES_FIELD_NUMBER: _ClassVar[int]
    NEW_FACE_DEGREES_FIELD_NUMBER: _ClassVar[int]
    PATCH_FACES_FIELD_NUMBER: _ClassVar[int]
    PATCH_RINGS_FIELD_NUMBER: _ClassVar[int]
    KNOWN_VERTICES_FIELD_NUMBER: _ClassVar[int]
    TOKENS_FIELD_NUMBER: _ClassVar[int]
    CANDIDATES_FIELD_NUMBER: _ClassVar[int]
    FALLBACK_FIELD_NUMBER: _ClassVar[int]
    FILL_FIELD_NUMBER: _ClassVar[int]
    INPAINT_FIELD_NUMBER: _ClassVar[int]
    FLIPPED_ORIENTATION_FIELD_NUMBER: _ClassVar[int]
    WELDED_VERTICES_FIELD_NUMBER: _ClassVar[int]
    REGION_SHARE_FIELD_NUMBER: _ClassVar[int]
    AUTO_REGION_FIELD_NUMBER: _ClassVar[int]
    PASSES_FIELD_NUMBER: _ClassVar[int]
    REVERSED_FACES_FIELD_NUMBER: _ClassVar[int]
    FLIPPED_MESH_FIELD_NUMBER: _ClassVar[int]
    SAMPLINGS_FIELD_NUMBER: _ClassVar[int]
    HANDLES_ADDED_FIELD_NUMBER: _ClassVar[int]
    FINDINGS_FIELD_NUMBER: _ClassVar[int]
    FINDINGS_TOTAL_FIELD_NUMBER: _ClassVar[int]
    REGIONS_FIELD_NUMBER: _ClassVar[int]
    requested_faces: int
    region_faces: int
    grown_faces: int
    removed_vertices: int
    boundary_vertices: int
    loops: int
    new_vertices: int
    new_faces: int
    new_face_degrees: _containers.ScalarMap[int, int]
    patch_faces: int
    patch_rings: int
    known_vertices: int
    tokens: int
    candidates: int
    fallback: str
    fill: _containers.ScalarMap[str, int]
    inpaint: _containers.ScalarMap[str, int]
    flipped_orientation: bool
    welded_vertices: int
    region_share: float
    auto_region: str
    passes: int
    reversed_faces: int
    flipped_mesh: bool
    samplings: int
    handles_added: int
    findings: _containers.RepeatedCompositeFieldContainer[RepairFinding]
    findings_total: int
    regions: _containers.RepeatedCompositeFieldContainer[RepairRegion]
    def __init__(self, requested_faces: _Optional[int] = ..., region_faces: _Optional[int] = ..., grown_faces: _Optional[int] = ..., removed_vertices: _Optional[int] = ..., boundary_vertices: _Optional[int] = ..., loops: _Optional[int] = ..., new_vertices: _Optional[int] = ..., new_faces: _Optional[int] = ..., new_face_degrees: _Optional[_Mapping[int, int]] = ..., patch_faces: _Optional[int] = ..., patch_rings: _Optional[int] = ..., known_vertices: _Optional[int] = ..., tokens: _Optional[int] = ..., candidates: _Optional[int] = ..., fallback: _Optional[str] = ..., fill: _Optional[_Mapping[str, int]] = ..., inpaint: _Optional[_Mapping[str, int]] = ..., flipped_orientation: _Optional[bool] = ..., welded_vertices: _Optional[int] = ..., region_share: _Optional[float] = ..., auto_region: _Optional[str] = ..., passes: _Optional[int] = ..., reversed_faces: _Optional[int] = ..., flipped_mesh: _Optional[bool] = ..., samplings: _Optional[int] = ..., handles_added: _Optional[int] = ..., findings: _Optional[_Iterable[_Union[RepairFinding, _Mapping]]] = ..., findings_total: _Optional[int] = ..., regions: _Optional[_Iterable[_Union[RepairRegion, _Mapping]]] = ...) -> None: ...

class RepairFinding(_message.Message):
    __slots__ = ("kind", "size", "vertex", "region", "action", "filled_by")
    KIND_FIELD_NUMBER: _ClassVar[int]
    SIZE_FIELD_NUMBER: _ClassVar[int]
    VERTEX_FIELD_NUMBER: _ClassVar[int]
    REGION_FIELD_NUMBER: _ClassVar[int]
    ACTION_FIELD_NUMBER: _ClassVar[int]
    FILLED_BY_FIELD_NUMBER: _ClassVar[int]
    kind: str
    size: int
    vertex: int
    region: int
    action: str
    filled_by: str
    def __init__(self, kind: _Optional[str] = ..., size: _Optional[int] = ..., vertex: _Optional[int] = ..., region: _Optional[int] = ..., action: _Optional[str] = ..., filled_by: _Optional[str] = ...) -> None: ...

class RepairRegion(_message.Message):
    __slots__ = ("id", "requested_faces", "region_faces", "grown_faces", "share", "strategy", "reason", "passes", "filled_by")
    ID_FIELD_NUMBER: _ClassVar[int]
    REQUESTED_FACES_FIELD_NUMBER: _ClassVar[int]
    REGION_FACES_FIELD_NUMBER: _ClassVar[int]
    GROWN_FACES_FIELD_NUMBER: _ClassVar[int]
    SHARE_FIELD_NUMBER: _ClassVar[int]
    STRATEGY_FIELD_NUMBER: _ClassVar[int]
    REASON_FIELD_NUMBER: _ClassVar[int]
    PASSES_FIELD_NUMBER: _ClassVar[int]
    FILLED_BY_FIELD_NUMBER: _ClassVar[int]
    id: int
    requested_faces: int
    region_faces: int
    grown_faces: int
    share: float
    strategy: str
    reason: str
    passes: int
    filled_by: str
    def __init__(self, id: _Optional[int] = ..., requested_faces: _Optional[int] = ..., region_faces: _Optional[int] = ..., grown_faces: _Optional[int] = ..., share: _Optional[float] = ..., strategy: _Optional[str] = ..., reason: _Optional[str] = ..., passes: _Optional[int] = ..., filled_by: _Optional[str] = ...) -> None: ...

class Progress(_message.Message):
    __slots__ = ("step", "total", "stage", "fraction")
    STEP_FIELD_NUMBER: _ClassVar[int]
    TOTAL_FIELD_NUMBER: _ClassVar[int]
    STAGE_FIELD_NUMBER: _ClassVar[int]
    FRACTION_FIELD_NUMBER: _ClassVar[int]
    step: int
    total: int
    stage: str
    fraction: float
    def __init__(self, step: _Optional[int] = ..., total: _Optional[int] = ..., stage: _Optional[str] = ..., fraction: _Optional[float] = ...) -> None: ...

class GenerateEvent(_message.Message):
    __slots__ = ("progress", "mesh")
    PROGRESS_FIELD_NUMBER: _ClassVar[int]
    MESH_FIELD_NUMBER: _ClassVar[int]
    progress: Progress
    mesh: MeshReply
    def __init__(self, progress: _Optional[_Union[Progress, _Mapping]] = ..., mesh: _Optional[_Union[MeshReply, _Mapping]] = ...) -> None: ...

class RepairRequest(_message.Message):
    __slots__ = ("mesh", "filename", "faces", "format", "seed", "steps", "region", "weld", "sampler", "max_growth")
    MESH_FIELD_NUMBER: _ClassVar[int]
    FILENAME_FIELD_NUMBER: _ClassVar[int]
    FACES_FIELD_NUMBER: _ClassVar[int]
    FORMAT_FIELD_NUMBER: _ClassVar[int]
    SEED_FIELD_NUMBER: _ClassVar[int]
    STEPS_FIELD_NUMBER: _ClassVar[int]
    REGION_FIELD_NUMBER: _ClassVar[int]
    WELD_FIELD_NUMBER: _ClassVar[int]
    SAMPLER_FIELD_NUMBER: _ClassVar[int]
    MAX_GROWTH_FIELD_NUMBER: _ClassVar[int]
    mesh: bytes
    filename: str
    faces: _containers.RepeatedScalarFieldContainer[int]
    format: str
    seed: int
    steps: int
    region: Region
    weld: bool
    sampler: str
    max_growth: float
    def __init__(self, mesh: _Optional[bytes] = ..., filename: _Optional[str] = ..., faces: _Optional[_Iterable[int]] = ..., format: _Optional[str] = ..., seed: _Optional[int] = ..., steps: _Optional[int] = ..., region: _Optional[_Union[Region, _Mapping]] = ..., weld: _Optional[bool] = ..., sampler: _Optional[str] = ..., max_growth: _Optional[float] = ...) -> None: ...

class Region(_message.Message):
    __slots__ = ("faces", "vertices", "sphere", "box", "auto_region")
    FACES_FIELD_NUMBER: _ClassVar[int]
    VERTICES_FIELD_NUMBER: _ClassVar[int]
    SPHERE_FIELD_NUMBER: _ClassVar[int]
    BOX_FIELD_NUMBER: _ClassVar[int]
    AUTO_REGION_FIELD_NUMBER: _ClassVar[int]
    faces: Indices
    vertices: Indices
    sphere: Sphere
    box: Box
    auto_region: str
    def __init__(self, faces: _Optional[_Union[Indices, _Mapping]] = ..., vertices: _Optional[_Union[Indices, _Mapping]] = ..., sphere: _Optional[_Union[Sphere, _Mapping]] = ..., box: _Optional[_Union[Box, _Mapping]] = ..., auto_region: _Optional[str] = ...) -> None: ...

class Indices(_message.Message):
    __slots__ = ("indices",)
    INDICES_FIELD_NUMBER: _ClassVar[int]
    indices: _containers.RepeatedScalarFieldContainer[int]
    def __init__(self, indices: _Optional[_Iterable[int]] = ...) -> None: ...

class Sphere(_message.Message):
    __slots__ = ("center", "radius")
    CENTER_FIELD_NUMBER: _ClassVar[int]
    RADIUS_FIELD_NUMBER: _ClassVar[int]
    center: _containers.RepeatedScalarFieldContainer[float]
    radius: float
    def __init__(self, center: _Optional[_Iterable[float]] = ..., radius: _Optional[float] = ...) -> None: ...

class Box(_message.Message):
    __slots__ = ("min", "max")
    MIN_FIELD_NUMBER: _ClassVar[int]
    MAX_FIELD_NUMBER: _ClassVar[int]
    min: _containers.RepeatedScalarFieldContainer[float]
    max: _containers.RepeatedScalarFieldContainer[float]
    def __init__(self, min: _Optional[_Iterable[float]] = ..., max: _Optional[_Iterable[float]] = ...) -> None: ...
