"""Type hints for viscd (the package over the extension viscd._viscd); docs/python.md."""

from typing import Any, Literal, Optional, Sequence, Tuple, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str
STATIC_BIT: int
"""Bit 31: reported indices of static objects have it set (k | STATIC_BIT)."""
MAX_COORDINATE: float
"""Largest magnitude of a coordinate or radius viscd accepts (1e18)."""

_Vec3 = Union[Sequence[float], npt.NDArray[np.floating]]
_Filter = Tuple[int, int]
_UInt32Array = npt.NDArray[np.uint32]

class PairCapError(RuntimeError):
    """A frame's pairs would exceed the Detector's pair_memory_cap."""

class BackendError(RuntimeError):
    """The backend itself failed (gl: no OpenGL 4.5 context, a GL error; cuda: no usable GPU, a CUDA error)."""

class Camera:
    """A pinhole camera: right-handed look-at, OpenGL clip space; width x height screen pixels."""

    eye: Tuple[float, float, float]
    target: Tuple[float, float, float]
    up: Tuple[float, float, float]
    fov_y_deg: float
    near: float
    far: float
    width: int
    height: int
    def __init__(
        self,
        eye: _Vec3,
        target: _Vec3,
        up: _Vec3 = (0.0, 1.0, 0.0),
        fov_y_deg: float = 60.0,
        near: float = 0.1,
        far: float = 1000.0,
        width: int = 1280,
        height: int = 720,
    ) -> None: ...

class Frame:
    """One frame's results; its arrays are views of the frame's own memory (no copy)."""

    @property
    def pairs(self) -> _UInt32Array:
        """(P, 2) uint32, sorted, i < j; a static object k appears as j = k | STATIC_BIT."""
    @property
    def state(self) -> npt.NDArray[np.uint8]:
        """(N,) uint8: 0 culled, 1 free, 2 colliding."""
    @property
    def pixels(self) -> npt.NDArray[np.float32]:
        """(N,) float32 screen pixels per object; empty when none were counted."""
    @property
    def began(self) -> _UInt32Array:
        """(B, 2) uint32 pairs that began (contact_events=True)."""
    @property
    def ended(self) -> _UInt32Array:
        """(E, 2) uint32 pairs that ended (contact_events=True)."""
    @property
    def image(self) -> Optional[npt.NDArray[np.uint8]]:
        """(H, W, 4) uint8 RGBA with shade=True and a camera; else None."""
    @property
    def static_pairs(self) -> _UInt32Array:
        """(Q, 2) uint32 copy: (i, k) for each moving object i overlapping static slot k."""
    @property
    def moving_pairs(self) -> _UInt32Array:
        """(P - Q, 2) uint32 copy: the pairs of two moving objects."""
    @property
    def stats(self) -> dict[str, Any]:
        """objects, static_objects, active, has_camera, has_pixels, mean_pixels, bits, layout,
        layout_order, layout_axis_bits, pairs, order_kept, followed_change, moved, replaced,
        stage_ms {stage: ms}, total_ms, detect_ms."""
    @property
    def input_copied(self) -> bool:
        """True when an input array was converted (copied) before the frame ran."""

class Detector:
    """Finds every overlapping pair among moving spheres or boxes, frame after frame."""

    def __init__(
        self,
        backend: Literal["cpu", "reference", "gl", "cuda"] = "cpu",
        *,
        lambda_: float = 200.0,
        pixels_for_32_bits: float = 100.0,
        pixels_for_64_bits: float = 400.0,
        bits: Union[Literal["adaptive"], Literal[16, 32, 64]] = "adaptive",
        layout: Literal["extended", "plain"] = "extended",
        culling: bool = True,
        map_width: int = 0,
        map_height: int = 0,
        shade: bool = False,
        report_pixels: bool = False,
        contact_events: bool = False,
        pair_memory_cap: int = 0,
        threads: int = 0,
        keep_order: bool = True,
        follow_change: bool = True,
        rest_margin: float = 0.0,
        move_margin: float = 8.0,
        simd: Literal["best", "sse2", "scalar"] = "best",
        gl_geometry: Literal["impostor", "mesh", "splat"] = "impostor",
        gl_counter: Literal["ssbo", "atomic_uint"] = "ssbo",
        gl_debug: bool = False,
        gl_initial_pair_capacity: int = 65536,
        gl_sync_layout: bool = False,
    ) -> None: ...
    def detect(
        self,
        spheres: Optional[npt.ArrayLike] = None,
        boxes: Optional[npt.ArrayLike] = None,
        camera: Optional[Camera] = None,
        filters: Optional[npt.ArrayLike] = None,
        id_map: Optional[npt.ArrayLike] = None,
        always_active: Optional[npt.ArrayLike] = None,
        moved: Optional[npt.ArrayLike] = None,
    ) -> Frame:
        """Runs one frame: (N, 4) float32 spheres or (N, 6) float32 boxes in, a Frame out."""
    def set_static(
        self,
        spheres: Optional[npt.ArrayLike] = None,
        boxes: Optional[npt.ArrayLike] = None,
        filters: Optional[npt.ArrayLike] = None,
    ) -> None: ...
    def add_static_sphere(self, sphere: Sequence[float], filter: Optional[_Filter] = None) -> int: ...
    def add_static_box(self, box: Sequence[float], filter: Optional[_Filter] = None) -> int: ...
    def move_static(self, k: int, shape: Sequence[float]) -> None: ...
    def remove_static(self, k: int) -> None: ...
    def clear_static(self) -> None: ...
    @property
    def static_count(self) -> int: ...
    @property
    def static_kind(self) -> Literal["sphere", "box"]: ...
    def ray_cast(
        self, origin: _Vec3, direction: _Vec3, max_t: float = ..., filter: Optional[_Filter] = None
    ) -> Optional[Tuple[int, float]]: ...
    def ray_cast_all(
        self, origin: _Vec3, direction: _Vec3, max_t: float = ..., filter: Optional[_Filter] = None
    ) -> Tuple[_UInt32Array, npt.NDArray[np.float32]]: ...
    def overlap(
        self,
        sphere: Optional[Sequence[float]] = None,
        box: Optional[Sequence[float]] = None,
        filter: Optional[_Filter] = None,
    ) -> _UInt32Array: ...
    def reset_events(self) -> None: ...
    def wait_for_stage_times(self, frame: Frame) -> None: ...
    @property
    def config(self) -> dict[str, Any]: ...
    def set_config(self, **config: Any) -> None: ...
    @property
    def backend(self) -> str: ...
    @property
    def memory_bytes(self) -> int: ...

class DistributedFrame:
    """One rank's share of a frame (DistributedDetector.detect())."""
    @property
    def pairs(self) -> npt.NDArray[np.uint64]: ...
    @property
    def state(self) -> npt.NDArray[np.uint8]: ...
    @property
    def stats(self) -> dict[str, Any]: ...

class DistributedDetector:
    """Every overlapping pair over the ranks of an mpi4py communicator (docs/mpi.md); loaded on first
    use. Every call but set_static and clear_static is collective."""
    def __init__(self, comm: Any, **config: Any) -> None: ...
    def detect(
        self,
        spheres: Optional[npt.ArrayLike] = None,
        boxes: Optional[npt.ArrayLike] = None,
        ids: Optional[npt.ArrayLike] = None,
        filters: Optional[npt.ArrayLike] = None,
        always_active: Optional[npt.ArrayLike] = None,
    ) -> DistributedFrame: ...
    def set_static(
        self,
        spheres: Optional[npt.ArrayLike] = None,
        boxes: Optional[npt.ArrayLike] = None,
        ids: Optional[npt.ArrayLike] = None,
        filters: Optional[npt.ArrayLike] = None,
    ) -> None: ...
    def clear_static(self) -> None: ...
    def gather_pairs(self, frame: DistributedFrame, root: int = 0) -> Optional[npt.NDArray[np.uint64]]: ...
    @property
    def rank(self) -> int: ...
    @property
    def size(self) -> int: ...

def pairs_within(points: npt.ArrayLike, r: Union[float, npt.ArrayLike], *, threads: int = 0) -> _UInt32Array:
    """(P, 2) uint32 pairs i < j, sorted, with |p_i - p_j| <= r (or <= r_i + r_j for (N,) radii)."""

@overload
def is_static(index: int) -> bool: ...
@overload
def is_static(index: npt.ArrayLike) -> npt.NDArray[np.bool_]: ...
@overload
def static_slot(index: int) -> int: ...
@overload
def static_slot(index: npt.ArrayLike) -> _UInt32Array: ...
@overload
def static_index(k: int) -> int: ...
@overload
def static_index(k: npt.ArrayLike) -> _UInt32Array: ...
