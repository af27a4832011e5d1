"""Type stubs of skelform's native module (see the docstrings for what each does)."""

from os import PathLike
from typing import Any, Callable, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

Progress = Callable[[str, int, Optional[int]], Optional[bool]]
Point = Tuple[float, float, float]
Domain = Tuple[Point, Point]
ArrayLike = npt.ArrayLike

class Cancelled(RuntimeError): ...

class Mesh:
    def __init__(
        self,
        vertices: ArrayLike,
        faces: ArrayLike,
        normals: Optional[ArrayLike] = None,
    ) -> None: ...
    @staticmethod
    def read(path: Union[str, PathLike[str]]) -> Mesh: ...
    @property
    def vertices(self) -> npt.NDArray[np.float32]: ...
    @property
    def faces(self) -> npt.NDArray[np.int32]: ...
    @property
    def normals(self) -> npt.NDArray[np.float32]: ...
    @property
    def labels(self) -> npt.NDArray[np.int32]: ...
    @property
    def curves(self) -> npt.NDArray[np.int32]: ...
    @property
    def curve_labels(self) -> npt.NDArray[np.int32]: ...
    @property
    def stats(self) -> Optional[dict[str, Any]]: ...
    @property
    def method(self) -> Optional[str]: ...
    def write(
        self,
        path: Union[str, PathLike[str]],
        *,
        ascii: bool = False,
        curves: bool = True,
        normals: bool = True,
    ) -> None: ...
    def check(self) -> dict[str, Any]: ...
    def to_trimesh(self) -> Any: ...
    def to_pyvista(self) -> Any: ...

class Formula:
    def __init__(self, text: str) -> None: ...
    def eval(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> npt.NDArray[np.float64]: ...
    def __call__(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> npt.NDArray[np.float64]: ...
    def gradient(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> npt.NDArray[np.float64]: ...
    @property
    def source(self) -> str: ...

class Scene:
    @staticmethod
    def from_toml(text: str, name: str = "<string>") -> Scene: ...
    def mesh(
        self,
        *,
        resolution: Optional[int] = None,
        cell: Optional[float] = None,
        method: Optional[str] = None,
        pose: Optional[str] = None,
        threads: Optional[int] = None,
        refine: Optional[bool] = None,
        normals: Optional[bool] = None,
        max_memory: Optional[int] = None,
        seeds: Optional[Sequence[Point]] = None,
        progress: Optional[Progress] = None,
    ) -> Mesh: ...
    def eval(self, x: ArrayLike, y: ArrayLike, z: ArrayLike) -> npt.NDArray[np.float64]: ...
    @property
    def domain(self) -> Tuple[Tuple[float, float, float], Tuple[float, float, float]]: ...
    @property
    def method(self) -> str: ...
    @property
    def name(self) -> Optional[str]: ...
    @property
    def poses(self) -> list[str]: ...

def load_scene(path: Union[str, PathLike[str]], *, pose: Optional[str] = None) -> Scene: ...
def mesh(
    field: Union[Formula, str, Scene, Callable[[npt.NDArray[np.float64]], ArrayLike]],
    domain: Optional[Domain] = None,
    *,
    resolution: Optional[int] = None,
    cell: Optional[float] = None,
    method: Optional[str] = None,
    pose: Optional[str] = None,
    threads: Optional[int] = None,
    refine: Optional[bool] = None,
    normals: Optional[bool] = None,
    max_memory: Optional[int] = None,
    seeds: Optional[Sequence[Point]] = None,
    progress: Optional[Progress] = None,
) -> Mesh: ...
def marching_cubes_core(
    volume: npt.NDArray[Any],
    level: Optional[float],
    step: int,
    ascent: bool,
    allow_degenerate: bool,
    mask: Optional[npt.NDArray[np.bool_]],
    threads: Optional[int],
    progress: Optional[Progress],
) -> Tuple[
    npt.NDArray[np.float32],
    npt.NDArray[np.int32],
    npt.NDArray[np.float32],
    npt.NDArray[np.float32],
]: ...
