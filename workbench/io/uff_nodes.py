"""UFF nodes and directions against a model's sensors and excitation (CONTRACTS.md section 3).

A frame's UFF node is the point named by the number (``"4"`` is node 4), else the point's index in
``[points]`` + 1; a matrix model's is its dof table's ``node``. Directions 1, 2, 3 are ``ux``, ``uy``,
``uz`` and 4, 5, 6 are ``rx``, ``ry``, ``rz``.
"""

from __future__ import annotations

import re

from workbench.model.frame import Frame
from workbench.model.matrix_model import MatrixModel

__all__ = ["DIRECTION_CODES", "uff_points", "sensor_lookup"]

DIRECTION_CODES = {"ux": 1, "uy": 2, "uz": 3, "rx": 4, "ry": 5, "rz": 6}  # UFF record 6: +X..+Z translation, rotation


def _node_numbers(frame: Frame) -> dict[str, int]:
    """UFF node number of each frame point (CONTRACTS.md section 3): the point named by the number
    (``"4"`` is node 4); a frame with no point named by a number uses its index in ``[points]`` + 1.
    """
    named = {name: int(name) for name in frame.points if re.fullmatch(r"0|[1-9]\d*", name)}
    return named or {name: k + 1 for k, name in enumerate(frame.points)}


def uff_points(frame: Frame | MatrixModel) -> tuple[dict[str, tuple[int, int]], tuple[int, int] | None]:
    """UFF ``(node, direction)`` of each sensor (by name) and of the excitation (None without one).

    A frame's nodes are its points' numbers (`_node_numbers`); a matrix model's are its dof table's
    nodes (CONTRACTS.md section 3).
    """
    if isinstance(frame, MatrixModel):
        dofs = frame.dofs
        sensors = {s.name: (s.node, DIRECTION_CODES[s.component]) for s in frame.sensors}
        e = frame.excitation
        return sensors, None if e is None else (int(dofs.nodes[e]), DIRECTION_CODES[dofs.components[e]])
    numbering = _node_numbers(frame)
    sensors = {s.name: (numbering[s.point], DIRECTION_CODES[s.dof]) for s in frame.sensors}
    x = frame.excitation
    return sensors, None if x is None else (numbering.get(x.point, -1), DIRECTION_CODES[x.dof])


def sensor_lookup(frame: Frame | MatrixModel,
                   sensor_map: dict[tuple[int, int], str] | None) -> dict[tuple[int, int], str]:
    """``{(node, direction): sensor}``: ``sensor_map``, else the frame's own numbering."""
    frame_sensors = {point: name for name, point in uff_points(frame)[0].items()}
    lookup = frame_sensors if sensor_map is None else {(int(n), int(d)): s for (n, d), s in sensor_map.items()}
    known = {s.name for s in frame.sensors}
    for name in lookup.values():
        if name not in known:
            raise ValueError(f"sensor_map: {name!r} is not a sensor of {frame.source} "
                             f"(sensors: {', '.join(sorted(known)) or 'none'})")
    return lookup
