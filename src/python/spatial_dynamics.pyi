"""Rigid-body dynamics from URDF: inverse and forward dynamics, the mass matrix, frames, the
centre of mass and the derivatives of dynamics, over the Rust library spatial_dynamics_core.

Arguments are real numbers: numpy arrays of a float or integer dtype, or sequences of numbers
(anything but float64 C-contiguous aligned arrays is converted to float64; bool, complex,
strings, dates, objects, None and masked arrays raise TypeError). 1-D for one state, 2-D with
one state a row for N states, computed with the GIL released (on every core when the batch is
worth it) from a copy of the arguments taken at the call, and returned stacked (a leading axis
of N). SI units; ``q`` and ``v`` in the order of ``Model.v_names``; a floating base's
``q = [x y z qx qy qz qw]`` and ``v = [linear; angular]`` in the base frame; matrices
row-major.
"""

from os import PathLike
from typing import Literal, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_ArrayLike = Union[npt.NDArray[np.float64], Sequence[float], Sequence[Sequence[float]]]
_Array = npt.NDArray[np.float64]

class DynamicsError(ValueError):
    """Bad input (a NaN naming its coordinate, an unknown frame, a wrong shape naming the
    argument) or a URDF the library cannot build; the message is the library's. Arguments that
    are not real numbers raise TypeError, unreadable files the OSError subclass of their cause,
    results too big to allocate MemoryError."""

class Model:
    """A robot model built from URDF (immutable). Safe to share between threads. Pickles
    (as its URDF text and options); ``copy.copy`` and ``copy.deepcopy`` return the model
    itself."""

    @staticmethod
    def from_urdf(
        path: Union[str, PathLike[str]], floating_base: bool = False, ignore_mimic: bool = False
    ) -> Model:
        """The model of a URDF file (a regular file of at most 64 MiB). ``floating_base``: a
        free joint between the world and the root link; ``ignore_mimic``: mimic joints get
        coordinates of their own. A file that cannot be read raises the OSError subclass of its
        cause (FileNotFoundError, PermissionError, IsADirectoryError); a device, a FIFO, a
        bigger file or a URDF the library refuses raises DynamicsError naming the path."""
    @staticmethod
    def from_urdf_string(xml: str, floating_base: bool = False, ignore_mimic: bool = False) -> Model:
        """The model of URDF text."""
    def __copy__(self) -> Model:
        """The model itself (it is immutable)."""
    def __deepcopy__(self, memo: dict) -> Model:
        """The model itself (it is immutable)."""
    @property
    def nq(self) -> int:
        """Position coordinates."""
    @property
    def nv(self) -> int:
        """Velocity coordinates."""
    @property
    def v_names(self) -> list[str]:
        """The name of each velocity coordinate, in ``v`` order."""
    @property
    def link_names(self) -> list[str]:
        """The URDF links: the frames of ``frame_placement`` and ``frame_jacobian``."""
    @property
    def forward_dynamics_method(self) -> str:
        """The method ``forward_dynamics(method=None)`` uses: "aba", "crba" or "rnea_columns"."""
    def rnea(self, q: _ArrayLike, v: _ArrayLike, a: _ArrayLike) -> _Array:
        """Inverse dynamics ``tau = M(q) a + C(q, v) + g(q)``: ``(nv,)`` or ``(N, nv)``."""
    def gravity(self, q: _ArrayLike) -> _Array:
        """Generalized gravity ``g(q)``: ``(nv,)`` or ``(N, nv)``."""
    def forward_dynamics(
        self,
        q: _ArrayLike,
        v: _ArrayLike,
        tau: _ArrayLike,
        method: Optional[Literal["aba", "crba", "rnea_columns"]] = None,
    ) -> _Array:
        """Forward dynamics ``qdd = M(q)^-1 (tau - C(q, v) - g(q))``: ``(nv,)`` or ``(N, nv)``."""
    def mass_matrix(self, q: _ArrayLike) -> _Array:
        """The mass matrix ``M(q)``: ``(nv, nv)`` or ``(N, nv, nv)``."""
    def frame_placement(self, q: _ArrayLike, frame: str) -> Tuple[_Array, _Array]:
        """``(translation, rotation)`` of a link in the world (Pinocchio's ``oMf``):
        ``(3,)``, ``(3, 3)`` or ``(N, 3)``, ``(N, 3, 3)``."""
    def frame_jacobian(
        self,
        q: _ArrayLike,
        frame: str,
        reference: Literal["world", "local", "local_world_aligned"] = "world",
    ) -> _Array:
        """A link's Jacobian, rows ``[linear; angular]``: ``(6, nv)`` or ``(N, 6, nv)``."""
    def center_of_mass(self, q: _ArrayLike) -> Tuple[Union[float, _Array], _Array, _Array]:
        """The centre of mass of the moving bodies: ``(mass, com, J)``, their mass (links welded
        to the world left out, as Pinocchio's computeTotalMass), the position of their centre of
        mass and its Jacobian: a float, ``(3,)``, ``(3, nv)``; or ``(N,)``, ``(N, 3)``,
        ``(N, 3, nv)``."""
    def rnea_derivatives(self, q: _ArrayLike, v: _ArrayLike, a: _ArrayLike) -> Tuple[_Array, _Array, _Array]:
        """``(dtau_dq, dtau_dv, M)``, each ``(nv, nv)`` or ``(N, nv, nv)``."""
    def aba_derivatives(self, q: _ArrayLike, v: _ArrayLike, tau: _ArrayLike) -> Tuple[_Array, _Array, _Array]:
        """``(ddq_dq, ddq_dv, Minv)``, each ``(nv, nv)`` or ``(N, nv, nv)``."""
