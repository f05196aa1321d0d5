"""Type stubs of gelrig's native module (the classes and functions `gelrig` re-exports)."""

from os import PathLike
from typing import Any, Callable, Optional, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, PathLike[str]]
Frame = npt.NDArray[np.uint8]  # (height, width, 3)

__version__: str

class GelrigError(Exception):
    """An error from gelrig, with its message (the place and the fix)."""

class ProtocolError(GelrigError):
    """A protocol or rig that does not check."""

    diagnostics: list[dict[str, Any]]

class Protocol:
    @staticmethod
    def load(
        path: _Path,
        rig: Optional[_Path] = None,
        set: Optional[dict[str, str]] = None,
        name: Optional[str] = None,
    ) -> Protocol: ...
    @property
    def path(self) -> str: ...
    @property
    def name(self) -> str: ...
    @property
    def rig_path(self) -> str: ...
    @property
    def valid(self) -> bool: ...
    @property
    def diagnostics(self) -> list[dict[str, Any]]: ...
    def validate(self) -> list[str]: ...
    def plan_json(self) -> str: ...

class TrackResult:
    """One tracked frame: every reference marker, by id."""

    @property
    def ids(self) -> npt.NDArray[np.uint32]: ...
    @property
    def xy(self) -> npt.NDArray[np.float64]: ...
    @property
    def dxy(self) -> npt.NDArray[np.float64]: ...
    @property
    def state(self) -> list[str]: ...
    @property
    def confidence(self) -> npt.NDArray[np.float64]: ...
    @property
    def contact(self) -> Optional[dict[str, Optional[float]]]: ...
    def __len__(self) -> int: ...

class Tracker:
    """GelSight marker tracking on numpy frames, as `gelrig track`."""

    def __init__(
        self,
        reference: Frame,
        method: str = "centroid",
        mm_per_px: Optional[float] = None,
        contact: bool = True,
    ) -> None: ...
    def __len__(self) -> int: ...
    @property
    def reference_xy(self) -> npt.NDArray[np.float64]: ...
    def track(self, frame: Frame) -> TrackResult:
        """Track `frame`; a C-contiguous frame is read in place with the GIL released (do
        not write into it from another thread meanwhile), a strided view is copied."""

class ForceSensor:
    """A calibrated GelSight (`gelrig calibrate`'s sensor file) read frame by frame."""

    @staticmethod
    def load(path: _Path) -> ForceSensor: ...
    @property
    def path(self) -> str: ...
    def reset(self, reference: Frame) -> None: ...
    def read(self, frame: Frame, t_s: Optional[float] = None) -> dict[str, Any]: ...

class Shape:
    """A GelSight calibrated as a shape sensor (`gelrig shape calibrate`'s shape file),
    reading height maps from frames against the background it was loaded with."""

    @staticmethod
    def load(path: _Path, background: Frame, model: Optional[str] = None) -> Shape: ...
    @property
    def path(self) -> str: ...
    @property
    def mm_per_px(self) -> float: ...
    @property
    def figures(self) -> list[dict[str, Any]]: ...
    def height(self, frame: Frame) -> npt.NDArray[np.float32]:
        """float32 H×W, mm, positive out of the gel (a press reads negative), 0 untouched."""
    def stats(self) -> dict[str, Any]: ...

class Bench:
    """The simulated bench's camera for a contact given by hand."""

    def __init__(
        self,
        sensor: str = "box",
        indenter: Optional[dict[str, str]] = None,
        seed: int = 0,
        width: Optional[int] = None,
        height: Optional[int] = None,
        max_depth_mm: Optional[float] = None,
    ) -> None: ...
    @property
    def max_depth_mm(self) -> float: ...
    @property
    def size(self) -> tuple[int, int]: ...
    def reference(self) -> tuple[Frame, dict[str, float], dict[str, Any]]: ...
    def press(
        self,
        depth_mm: float,
        shear_mm: float = 0.0,
        twist_deg: float = 0.0,
        x_mm: float = 0.0,
        y_mm: float = 0.0,
    ) -> tuple[Frame, dict[str, float], dict[str, Any]]:
        """Press `depth_mm`, then move the indenter `shear_mm` along x and turn it
        `twist_deg` (the stage's moves from the pressed state): (frame, wrench, truth with
        the contact radius, stick fractions and every marker's exact centre)."""

def run(
    protocol: Protocol,
    out: _Path,
    seed: int = 0,
    time_scale: Optional[float] = None,
    on_event: Optional[Callable[[str], Any]] = None,
) -> tuple[str, str, Optional[str]]: ...
def read_manifest(dir: _Path) -> str: ...
def run_status(dir: _Path) -> str: ...
def read_image(path: _Path) -> Frame: ...
def read_frame(dir: _Path, index: int) -> Frame: ...
def report(dir: _Path, out: Optional[_Path] = None, sensor: Optional[_Path] = None) -> tuple[str, str]: ...
def export(dir: _Path, format: str, out: _Path) -> list[str]: ...
def list_runs(folder: _Path) -> str: ...
def cli(argv: list[str]) -> int: ...
def use_packaged_protocols(dir: _Path) -> bool: ...
