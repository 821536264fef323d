"""A structure given by its matrices (CONTRACTS.md section 4): the record and its modes.

`MatrixModel` is what `workbench.model.matrix_file.read_matrix_model` returns: a mass matrix, a rest
stiffness and one stiffness per bolted joint at its mean parameter, so that, as in the paper's
eq. (3)-(4), ``K(gamma) = K_rest + sum_j gamma_j K_j`` with ``gamma_j = Y_j / E[Y_j]``. The matrices
hold only the free dofs (supports are already applied by the program that exported them); the dof
table names each row by its node and component.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import scipy.sparse as sp

from workbench.model.frame import DEFAULT_DAMPING_RATIO
from workbench.model.pattern import JointPattern

__all__ = ["COMPONENTS", "DofTable", "MatrixJoint", "MatrixSensor", "MatrixModel"]

COMPONENTS = ("ux", "uy", "uz", "rx", "ry", "rz")


@dataclass(frozen=True, eq=False)
class DofTable:
    """What each matrix row is (``dofs.csv``).

    Attributes
    ----------
    nodes : (n,) integer node number of each row.
    components : (n,) component of each row, one of `COMPONENTS`.
    coordinates : (n, 3) x, y, z of each row's node, m, or None when dofs.csv has no coordinates.
    """

    nodes: np.ndarray
    components: tuple[str, ...]
    coordinates: np.ndarray | None = None
    _lookup: dict[tuple[int, str], int] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        n = self.nodes.shape[0]
        if self.nodes.ndim != 1 or len(self.components) != n:
            raise ValueError(f"DofTable: {n} nodes but {len(self.components)} components")
        if self.coordinates is not None and self.coordinates.shape != (n, 3):
            raise ValueError(f"DofTable: coordinates of shape {self.coordinates.shape}, expected ({n}, 3)")
        lookup = {(int(node), comp): i for i, (node, comp) in enumerate(zip(self.nodes, self.components))}
        if len(lookup) != n:
            raise ValueError("DofTable: a (node, component) pair appears twice")
        object.__setattr__(self, "_lookup", lookup)

    @property
    def size(self) -> int:
        return int(self.nodes.shape[0])

    def find(self, node: int, component: str) -> int | None:
        """Row of ``(node, component)``, or None when the table has no such dof."""
        return self._lookup.get((int(node), component))

    def node_components(self, node: int) -> tuple[str, ...]:
        """The components of ``node`` present in the table, in `COMPONENTS` order."""
        return tuple(c for c in COMPONENTS if (int(node), c) in self._lookup)

    def label(self, index: int) -> str:
        """``"node 1042 uz"``: the dof of row ``index``, for messages."""
        return f"node {int(self.nodes[index])} {self.components[index]}"


@dataclass(frozen=True)
class MatrixJoint:
    """A bolted joint of a matrix model: its stiffness is ``gamma K_j`` with ``gamma = Y / youngs_modulus``.

    Attributes
    ----------
    name : unique within the model.
    youngs_modulus : mean of the joint's parameter (an equivalent modulus), Pa.
    cov : coefficient of variation of the parameter (0: deterministic).
    group : joints of one group share one stochastic model when identified.
    """

    name: str
    youngs_modulus: float
    cov: float = 0.0
    group: str = ""


@dataclass(frozen=True)
class MatrixSensor:
    """A response location: ``dof`` is the row of ``(node, component)`` in the dof table."""

    name: str
    node: int
    component: str
    dof: int


@dataclass(frozen=True, eq=False)
class MatrixModel:
    """A validated matrix model (CONTRACTS.md section 4), on its free dofs.

    Attributes
    ----------
    name : the model's name.
    mass : (n, n) sparse mass matrix, kg (symmetric positive definite).
    stiffness_rest : (n, n) sparse stiffness outside the joints, N/m.
    stiffness_joints : one (n, n) sparse matrix per joint at its mean parameter (positive semi-definite).
    joints : the joints' parameters, in the order of ``stiffness_joints``.
    dofs : the dof table (node and component of each row).
    excitation : row of the excited dof, or None when the model has no ``[excitation]``.
    sensors : the response locations, in the file's order.
    damping_ratios : modal damping ratios, mode 1 first; the last value repeats.
    description, format, source : free text, ``"matrix-market"`` or ``"op4"``, the model file's path.
    """

    name: str
    mass: sp.csr_matrix
    stiffness_rest: sp.csr_matrix
    stiffness_joints: tuple[sp.csr_matrix, ...]
    joints: tuple[MatrixJoint, ...]
    dofs: DofTable
    excitation: int | None = None
    sensors: tuple[MatrixSensor, ...] = ()
    damping_ratios: tuple[float, ...] = (DEFAULT_DAMPING_RATIO,)
    description: str = ""
    format: str = "matrix-market"
    source: str = "<matrix model>"
    _pattern: JointPattern = field(init=False, repr=False)
    _joint_blocks: tuple[tuple[np.ndarray, sp.csr_matrix], ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        n = self.dofs.size
        for what, a in [("mass", self.mass), ("stiffness_rest", self.stiffness_rest),
                        *((f"stiffness_joints[{j}]", k) for j, k in enumerate(self.stiffness_joints))]:
            if a.shape != (n, n):
                raise ValueError(f"MatrixModel: {what} is {a.shape[0]} x {a.shape[1]}, the dof table has {n} rows")
        if len(self.joints) != len(self.stiffness_joints):
            raise ValueError(f"MatrixModel: {len(self.joints)} joints but {len(self.stiffness_joints)} "
                             "joint stiffnesses")
        object.__setattr__(self, "_pattern", JointPattern.of(self.stiffness_rest, self.stiffness_joints))
        object.__setattr__(self, "_joint_blocks", tuple(_block(k) for k in self.stiffness_joints))

    @property
    def size(self) -> int:
        return self.dofs.size

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(j.name for j in self.joints)

    @property
    def youngs_moduli(self) -> np.ndarray:
        """(n_joints,) mean parameter of each joint, Pa."""
        return np.array([j.youngs_modulus for j in self.joints], float)

    @property
    def covs(self) -> np.ndarray:
        """(n_joints,) coefficient of variation of each joint's parameter."""
        return np.array([j.cov for j in self.joints], float)

    @property
    def groups(self) -> tuple[str, ...]:
        return tuple(j.group for j in self.joints)

    @property
    def sensor_dofs(self) -> dict[str, int]:
        """Sensor name -> row of its dof."""
        return {s.name: s.dof for s in self.sensors}

    def damping_ratio(self, mode_count: int) -> tuple[float, ...]:
        """Modal damping ratios of the first `mode_count` modes; the last given value repeats."""
        r = self.damping_ratios
        return tuple(r[min(k, len(r) - 1)] for k in range(mode_count))

    def stiffness(self, gamma: np.ndarray | None = None) -> sp.csr_matrix:
        """``K(gamma) = K_rest + sum_j gamma_j K_j`` (eq. 3-4), N/m; ``gamma = None`` means all ones.

        Parameters
        ----------
        gamma : (n_joints,) normalised joint parameters ``Y_j / E[Y_j]``, finite and positive.
        """
        return self._pattern.stiffness(gamma, self.joint_names)

    def scaled(self, scale: np.ndarray) -> MatrixModel:
        """The model with joint j's mean parameter times ``scale[j]``, its matrix with it (eq. 3-4:
        ``K_j`` is the joint's stiffness at its mean, so it moves with the mean).
        """
        scale = np.asarray(scale, float)
        joints = tuple(replace(j, youngs_modulus=float(j.youngs_modulus * s)) for j, s in zip(self.joints, scale))
        return replace(self, joints=joints,
                       stiffness_joints=tuple((s * k).tocsr() for s, k in zip(scale, self.stiffness_joints)))

    def energies(self, shapes: np.ndarray, others: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """``x^T K_rest y`` (n_shapes,) and ``x^T K_j y`` per joint (n_joints, n_shapes): ``lambda_kj`` of eq. (5).

        Each joint's form is taken on the rows its matrix touches only, so that SMR1's sensitivities
        of 200 joints cost one product with ``K_rest`` and 200 small ones, not 200 on the whole model.
        ``shapes`` (x) and ``others`` (y, default x) are (n, n_shapes); joints at their mean (gamma = 1).
        """
        x = np.atleast_2d(shapes.T).T
        y = x if others is None else np.atleast_2d(others.T).T
        rest = np.einsum("ik,ik->k", x, self.stiffness_rest @ y)
        joints = np.empty((len(self.joints), x.shape[1]))
        for j, (rows, block) in enumerate(self._joint_blocks):
            joints[j] = np.einsum("ik,ik->k", x[rows], block @ y[rows])
        return rest, joints


def _block(matrix: sp.csr_matrix) -> tuple[np.ndarray, sp.csr_matrix]:
    """The rows a joint's matrix touches and the matrix on them: a joint acts on a few dofs of many."""
    rows = np.unique(sp.coo_matrix(matrix).row)
    return rows, sp.csr_matrix(matrix[rows][:, rows])
