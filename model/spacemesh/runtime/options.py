"""The options of one generate request, defined, defaulted and validated in one place.

REST, gRPC and both command lines build a :class:`GenerateOptions` from what the user
sent; :meth:`GenerateOptions.resolve` fills the model's defaults and checks every range
once, raising :class:`OptionError` (the service answers it with 422 problem+json, the
command lines with a one-line message and exit 2). The engine, the batcher and
:class:`~spacemesh.runtime.pipeline.MeshGenerator` then pass the resolved options along
unchanged. :data:`OPTION_FIELDS` lists the public names; the SDK mirrors them (a test
keeps the two in sync).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, fields, replace
from typing import TYPE_CHECKING, Any

from spacemesh.runtime.schedule import METHODS

if TYPE_CHECKING:
    from spacemesh.runtime.pipeline import ModelSpec

#: Where the vertices start: pure noise (the paper) or points chosen on the input.
START_MODES = ("noise", "points")
#: Most seeds one ``samples`` request may try.
MAX_SAMPLES = 16
#: Fewest vertices a mesh may be asked for (a tetrahedron).
MIN_TARGET_VERTICES = 4
#: Most vertices a mesh may be asked for.
MAX_TARGET_VERTICES = 10_000
#: Smallest and largest ``tolerance`` (fractions of the input's bounding-box diagonal).
MIN_TOLERANCE = 1e-4
MAX_TOLERANCE = 0.5
#: The vertex start a release records in ``manifest["sampler"]``: farthest-point
#: samples of the input, with points on sharp features counted twice as far
#: (``feature_boost``), not denoised (the shipped denoiser moves good vertices away
#: from the surface: docs/RESULTS.md has the start-time sweep), 200 of them unless the
#: request sets a target.
POINTS_START = {"start": "points", "start_time": 0.0, "vertices": 200, "feature_boost": 1.0}
#: Seeds tried beyond a request's own when none of its meshes has as many pieces as the
#: points (:mod:`spacemesh.runtime.pieces`).
PIECE_RETRY_SEEDS = 4
#: Largest seed (int64 in the gRPC contract; seeds + samples + retries stay below it).
MAX_SEED = 2**63 - 1 - MAX_SAMPLES - PIECE_RETRY_SEEDS


class OptionError(ValueError):
    """An option the model cannot honour.

    Attributes
    ----------
    option : str
        The option's public name.
    """

    def __init__(self, option: str, message: str) -> None:
        super().__init__(message)
        self.option = option


@dataclass(frozen=True)
class GenerateOptions:
    """What a generate request may choose; None means the model's default.

    Attributes
    ----------
    seed : int
        The same seed (and options) gives the same mesh.
    steps : int, optional
        Sampler steps of the whole schedule (with ``start=points`` only those below
        ``start_time`` run).
    sampler : {"ddim", "ddpm"}, optional
    start : {"noise", "points"}, optional
        ``noise``: the paper's diffusion from pure noise. ``points``: vertices chosen on
        the input by farthest-point sampling, noised to ``start_time`` and denoised from
        there (SDEdit).
    start_time : float, optional
        Fraction t/T of the diffusion where ``start=points`` begins; 0 uses the chosen
        points as they are. Only with ``start=points``.
    target_vertices : int, optional
        Vertices of the final mesh (within 10%); without it the count is a fixed
        function of the input (the same for every seed).
    tolerance : float, optional
        The mesh's size is the smallest the search finds whose mean distance from the
        input points to the mesh is at most this fraction of the input's bounding-box
        diagonal (the fit report's ``points_to_mesh_mean_rel``; ``tolerance_met`` says
        whether it was reached within the search's cap). Not with ``target_vertices``;
        needs ``start=points``.
    samples : int
        Seeds ``seed .. seed + samples - 1`` are generated and the mesh that fits the
        input best is returned (ties: the lower seed).
    raw : bool
        Return the networks' mesh as the model's own decode gives it, without the
        geometry stage (:mod:`spacemesh.geometry`).
    """

    seed: int = 0
    steps: int | None = None
    sampler: str | None = None
    start: str | None = None
    start_time: float | None = None
    target_vertices: int | None = None
    tolerance: float | None = None
    samples: int = 1
    raw: bool = False

    def resolve(self, spec: ModelSpec) -> GenerateOptions:
        """These options with the model's defaults filled in, every range checked.

        Parameters
        ----------
        spec : ModelSpec

        Returns
        -------
        GenerateOptions
            No field is None except ``target_vertices``, ``tolerance`` and, with
            ``start=noise``, ``start_time``; resolving it again gives it back unchanged.

        Raises
        ------
        OptionError
            The first option out of range, by its public name.
        """
        _integer("seed", self.seed, 0, MAX_SEED)
        steps = spec.steps if self.steps is None else _integer(
            "steps", self.steps, 1, spec.schedule.timesteps)
        sampler = spec.method if self.sampler is None else str(self.sampler)
        if sampler not in METHODS:
            raise OptionError("sampler", f"sampler must be one of {', '.join(METHODS)}, "
                                         f"not {sampler!r}")
        start = spec.start if self.start is None else str(self.start)
        if start not in START_MODES:
            raise OptionError("start", f"start must be one of {', '.join(START_MODES)}, "
                                       f"not {start!r}")
        if start == "noise" and self.start_time is not None:
            raise OptionError("start_time", "start_time applies to start=points only")
        start_time: float | None  # None with start=noise: the whole diffusion
        start_time = spec.start_time if self.start_time is None else self.start_time
        if start == "points":
            try:
                start_time = float(start_time)
            except (TypeError, ValueError):
                raise OptionError("start_time", f"start_time must be a number, not "
                                                f"{self.start_time!r}") from None
            if not 0.0 <= start_time <= 1.0:  # NaN fails too
                raise OptionError("start_time",
                                  f"start_time must be in [0, 1], not {self.start_time}")
        else:
            start_time = None  # the whole diffusion
        if self.target_vertices is not None:
            _integer("target_vertices", self.target_vertices, MIN_TARGET_VERTICES,
                     MAX_TARGET_VERTICES)
            if start == "noise":
                raise OptionError("target_vertices",
                                  "target_vertices needs start=points (from noise the "
                                  "network picks the count)")
        tolerance = None if self.tolerance is None else _tolerance(self.tolerance)
        if tolerance is not None:
            if self.target_vertices is not None:
                raise OptionError("tolerance", "tolerance and target_vertices cannot both be "
                                               "set: the tolerance chooses the vertex count")
            if start == "noise":
                raise OptionError("tolerance", "tolerance needs start=points (from noise the "
                                               "network picks the count)")
        _integer("samples", self.samples, 1, MAX_SAMPLES)
        if not isinstance(self.raw, bool):
            raise OptionError("raw", f"raw must be true or false, not {self.raw!r}")
        return replace(self, steps=steps, sampler=sampler, start=start, start_time=start_time,
                       tolerance=tolerance)

    def to_dict(self) -> dict[str, Any]:
        """The options by public name."""
        return asdict(self)


#: Public option names, in the order of :class:`GenerateOptions`.
OPTION_FIELDS = tuple(f.name for f in fields(GenerateOptions))


def _tolerance(value: Any) -> float:
    """``value`` as a float in ``[MIN_TOLERANCE, MAX_TOLERANCE]``."""
    if isinstance(value, bool):
        raise OptionError("tolerance", f"tolerance must be a number, not {value!r}")
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise OptionError("tolerance", f"tolerance must be a number, not {value!r}") from None
    if not MIN_TOLERANCE <= number <= MAX_TOLERANCE:  # NaN fails too
        raise OptionError("tolerance", f"tolerance must be in {MIN_TOLERANCE:g}..."
                                       f"{MAX_TOLERANCE:g} of the diagonal, not {value}")
    return number


def _integer(name: str, value: Any, low: int, high: int) -> int:
    """``value`` as an int in ``[low, high]`` (bools and fractions refused)."""
    if isinstance(value, bool):
        raise OptionError(name, f"{name} must be an integer, not {value!r}")
    if not isinstance(value, int):
        try:
            number = float(value)
        except (TypeError, ValueError):
            raise OptionError(name, f"{name} must be an integer, not {value!r}") from None
        if not number.is_integer():
            raise OptionError(name, f"{name} must be an integer, not {value!r}")
        value = int(number)
    if not low <= value <= high:
        raise OptionError(name, f"{name} must be in {low}..{high}, not {value}")
    return int(value)
