"""The body graph of a robot (tree joints and loop closures) with every joint's twists, and the
limbs' connected groups and paths through it."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from kinematics.model.robot import Robot, matrix


@dataclass(frozen=True)
class Edge:
    """A joint of the graph between two Pinocchio bodies (0 = ground).

    Attributes:
        name: joint or closure name.
        kind: "joint" (tree) or "point"/"6d" (loop closure).
        parent, child: body indices; the twist is the child's motion relative to the parent.
        dofs: columns of this edge's freedoms in the graph's rate vector.
    """

    name: str
    kind: str
    parent: int
    child: int
    dofs: tuple[int, ...]


@dataclass
class JointGraph:
    """Bodies, joints (tree + closures) and their twists at one configuration."""

    edges: list[Edge]
    twists: np.ndarray  # 6 x n_rates, WORLD frame (v_O; w)
    platform: int  # body carrying the end-effector frame
    n_bodies: int


def joint_graph(robot: Robot, q: np.ndarray) -> JointGraph:
    """The body graph of a robot at configuration q, with every joint's twists."""
    model = robot.model
    data = model.createData()
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    edges: list[Edge] = []
    columns: list[np.ndarray] = []
    for jid in range(1, model.njoints):
        joint = model.joints[jid]
        J = matrix(pin.getJointJacobian(model, data, jid, pin.WORLD), model.nv)[:, joint.idx_v : joint.idx_v + joint.nv]
        start = len(columns)
        columns.extend(J.T)
        edges.append(Edge(model.names[jid], "joint", int(model.parents[jid]), jid,
                          tuple(range(start, start + joint.nv))))
    if robot.loops is not None:
        for c in robot.loops.closures:
            f1 = robot.frame_id(c.frame1)
            f2 = robot.frame_id(c.frame2)
            start = len(columns)
            if c.type == "point":
                centre = data.oMf[f1].translation
                for axis in np.eye(3):  # rotations about the closure point
                    columns.append(np.concatenate([np.cross(centre, axis), axis]))
            edges.append(Edge(c.name, c.type, int(model.frames[f1].parentJoint), int(model.frames[f2].parentJoint),
                              tuple(range(start, len(columns)))))
    ee = robot.loops.end_effector if robot.loops is not None else robot.tool_frame
    platform = int(model.frames[robot.frame_id(ee)].parentJoint)
    twists = np.array(columns).T if columns else np.zeros((6, 0))
    return JointGraph(edges, twists, platform, model.njoints)


def components(graph: JointGraph) -> list[set[int]]:
    """Connected groups of bodies once ground and platform are removed."""
    skip = {0, graph.platform}
    adj: dict[int, set[int]] = {}
    for e in graph.edges:
        if e.parent not in skip and e.child not in skip:
            adj.setdefault(e.parent, set()).add(e.child)
            adj.setdefault(e.child, set()).add(e.parent)
        for b in (e.parent, e.child):
            if b not in skip:
                adj.setdefault(b, set())
    seen: set[int] = set()
    groups = []
    for start in sorted(adj):
        if start in seen:
            continue
        group, stack = set(), [start]
        while stack:
            b = stack.pop()
            if b in group:
                continue
            group.add(b)
            stack.extend(adj[b] - group)
        seen |= group
        groups.append(group)
    return groups


def simple_paths(edges: list[Edge], start: int, goal: int, limit: int = 64) -> list[list[tuple[Edge, int]]]:
    """Simple paths start -> goal as lists of (edge, +1 forward / -1 backward)."""
    out: list[list[tuple[Edge, int]]] = []

    def walk(node: int, visited: set[int], path: list[tuple[Edge, int]]) -> None:
        if len(out) >= limit:
            return
        if node == goal:
            out.append(list(path))
            return
        for e in edges:
            for a, b, sign in ((e.parent, e.child, 1), (e.child, e.parent, -1)):
                if a == node and b not in visited:
                    path.append((e, sign))
                    walk(b, visited | {b}, path)
                    path.pop()

    walk(start, {start}, [])
    return out

