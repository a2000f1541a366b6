"""A stepper's state as named arrays, the form a checkpoint stores: each solver state dataclass
to and from arrays (:func:`to_arrays`, :func:`from_arrays`), and for each distributed array a
:class:`Layout`, where its local rows live, keyed by reference coordinates. The fluid's, the
structure's and the wall indices' layouts and the loading of the solvers' states are here too;
fsi/run/checkpoint.py writes and reads the arrays.
"""

from __future__ import annotations

import dataclasses
import logging
import typing
from dataclasses import dataclass

import numpy as np

from fsi import compat
from fsi.output.wall_outputs import FluidOutputs
from fsi.physics import fluid, solid

log = logging.getLogger("fsi")


# --------------------------------------------------------------------------------------------
# Layouts: where the rows of a distributed array live


@dataclass(frozen=True)
class Layout:
    """The local rows of distributed arrays (a Function's values, or an interface vector):
    ``points`` a key per local row (owned rows first; NaN for a ghost row on no local cell),
    ``owned`` the number of owned rows, ``block`` the values per row. An array of this layout
    has shape (rows · block, ...) (extra axes: e.g. columns of interface vectors)."""

    name: str
    points: np.ndarray
    owned: int
    block: int


def space_layout(name: str, V) -> Layout:
    """The layout of the values of a (blocked) Lagrange space: one row per node, keyed by the
    node's coordinates. Call it while the mesh is in its reference configuration."""
    gdim = V.mesh.geometry.dim
    points = V.tabulate_dof_coordinates()[:, :gdim].copy()
    used = np.zeros(len(points), dtype=bool)
    used[np.unique(compat.cell_dofs(V))] = True
    points[~used] = np.nan  # a submesh's orphan ghost (dolfinx 0.5): never read
    return Layout(name, points, V.dofmap.index_map.size_local, V.dofmap.index_map_bs)


def mixed_layout(name: str, W, parts: typing.Sequence[tuple[np.ndarray, Layout]]) -> Layout:
    """The layout of a mixed space's values (one value per row), keyed by the node coordinates
    and the component number over the parts: ``parts`` pairs each sub-space's layout with the
    mixed dof behind each of its (unrolled) dofs (−1: none)."""
    index_map = W.dofmap.index_map
    size = (index_map.size_local + index_map.num_ghosts) * W.dofmap.index_map_bs
    gdim = parts[0][1].points.shape[1]
    points = np.full((size, gdim + 1), np.nan)
    component = 0
    for to_mixed, layout in parts:
        for c in range(layout.block):
            dofs = to_mixed[c :: layout.block]
            ok = dofs >= 0
            points[dofs[ok], :gdim] = layout.points[ok]
            points[dofs[ok], gdim] = component
            component += 1
    return Layout(name, points, index_map.size_local * W.dofmap.index_map_bs, 1)


def interface_layout(name: str, points: np.ndarray, block: int) -> Layout:
    """Owned entries only, ``block`` values (a flat interface vector: gdim) at each of
    ``points`` (n, gdim)."""
    return Layout(name, np.asarray(points, dtype=float), len(points), block)


def layout_of(key: str, layouts: dict[str, Layout]) -> Layout | None:
    """The layout of array ``key``: ``layouts[name]`` for ``key == name`` or ``key`` starting
    with ``name + "."`` (e.g. ``coupling.iqn.V`` for ``coupling.iqn.V.0``); None: global."""
    for name, layout in layouts.items():
        if key == name or key.startswith(name + "."):
            return layout
    return None


# --------------------------------------------------------------------------------------------
# State dataclasses <-> named arrays


def to_arrays(prefix: str, state) -> dict[str, np.ndarray]:
    """The fields of a state dataclass (e.g. :class:`fsi.physics.fluid.FluidState`) as arrays named
    ``prefix + field``; ``None`` becomes an empty array."""
    return {
        prefix + f.name: (
            np.zeros(0) if (v := getattr(state, f.name)) is None else np.array(v, copy=True)
        )
        for f in dataclasses.fields(state)
    }


def from_arrays(cls, prefix: str, arrays: dict[str, np.ndarray]):
    """The state dataclass ``cls`` from :func:`to_arrays`'s arrays (0-d arrays become Python
    scalars, an empty array ``None`` where the field allows it)."""
    hints = typing.get_type_hints(cls)
    values = {}
    for f in dataclasses.fields(cls):
        a = arrays[prefix + f.name]
        optional = type(None) in typing.get_args(hints[f.name])
        if optional and a.size == 0:
            values[f.name] = None
        elif a.ndim == 0:
            values[f.name] = a.item()
        else:
            values[f.name] = a.copy()
    return cls(**values)


def subset(prefix: str, arrays: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The arrays named ``prefix...``, with the prefix removed."""
    return {k[len(prefix) :]: v for k, v in arrays.items() if k.startswith(prefix)}


# --------------------------------------------------------------------------------------------
# The solvers' states and their layouts

# Checkpoint layouts of the solvers' states


def fluid_layouts(solver: fluid.FluidSolver) -> dict[str, Layout]:
    """The rows of :class:`fsi.physics.fluid.FluidState`'s arrays: ``U`` on the mixed space
    (velocity and pressure nodes), ``u_n``/``u_nm1`` on the velocity's P2 nodes, the mesh
    displacement history and ``w`` on the P1 vertices. Call it before the mesh moves."""
    velocity = space_layout("fluid_velocity", solver.V)
    pressure = space_layout("fluid_pressure", solver.Q)
    V_to_W, Q_to_W = solver.mixed_dofs()
    mixed = mixed_layout("fluid_mixed", solver.W, [(V_to_W, velocity), (Q_to_W, pressure)])
    vertices = space_layout("fluid_vertices", solver.ale.space)
    return {
        "fluid.U": mixed,
        "fluid.u_n": velocity,
        "fluid.u_nm1": velocity,
        **{f"fluid.{name}": vertices for name in ("d", "d_n", "d_nm1", "w")},
    }


def fluid_state(solver: fluid.FluidSolver, state: dict[str, np.ndarray]) -> fluid.FluidState:
    """The fluid's state from ``fluid.*`` arrays. The lumped outlets' state (a Windkessel's
    P_c^n, P_c^{n−1}; fsi.run.checkpoint.VARIABLE) is restored if it fits this run's outlets; one
    that does not (a checkpoint written before outlets had a state, or by a run with another
    kind of outlet) starts them from their initial state (P_0), with a warning."""
    initial = np.concatenate([np.zeros(0), *(o.model.initial_state() for o in solver.lumped)])
    stored = state.get("fluid.outlet_state")
    if stored is None or stored.shape != initial.shape:
        if initial.size and solver.comm.rank == 0:
            log.warning(
                "fsi: the checkpoint holds no state of this run's fluid.outlet (written "
                "with another kind of outlet): it starts from its initial_pressure at "
                "t = %g s",
                float(state["fluid.time"]),
            )
        state = {**state, "fluid.outlet_state": initial}
    return from_arrays(fluid.FluidState, "fluid.", state)


def structure_layouts(solver: solid.SolidSolver) -> dict[str, Layout]:
    """The rows of :class:`fsi.physics.solid.SolidState`'s arrays: η and its history, the tractions
    on the displacement space's nodes; the nodal interface forces, arrays (n, gdim), on the owned
    interface nodes (one row each)."""
    nodes = space_layout("solid", solver.V)
    forces = interface_layout("interface_nodes", solver.interface_points, 1)
    return {
        **{
            f"solid.{name}": nodes
            for name in ("eta", "eta_n", "v_n", "a_n", "traction", "traction_n")
        },
        "solid.forces": forces,
        "solid.forces_n": forces,
        **({"solid.reference_offset": nodes} if solver.prestress is not None else {}),
    }


def solid_arrays(solver: solid.SolidSolver) -> dict[str, np.ndarray]:
    """The solid's state as ``solid.*`` arrays (:class:`fsi.physics.solid.SolidState`) and, when
    prestressed, the stress-free reference's offset U₀ (``solid.reference_offset``)."""
    arrays = to_arrays("solid.", solver.save_state())
    if solver.prestress is not None:
        arrays["solid.reference_offset"] = solver.prestress.offset.x.array.copy()
    return arrays


def load_solid(solver: solid.SolidSolver, state: dict[str, np.ndarray]) -> None:
    """The solid's state from ``solid.*`` arrays (and the prestress's reference, which the
    checkpoint holds, over the one the run computed); the rates of the last step η̇, η̈ (outputs,
    recomputed by every step) as :meth:`fsi.physics.solid.SolidSolver.advance` leaves them;
    stresses."""
    solver.restore_state(from_arrays(solid.SolidState, "solid.", state))
    if solver.prestress is not None and "solid.reference_offset" in state:
        solver.prestress.offset.x.array[:] = state["solid.reference_offset"]
    solver.v.x.array[:] = solver.v_n.x.array
    solver.a.x.array[:] = solver.a_n.x.array
    solver.stress.update()


def wall_index_layouts(outputs: FluidOutputs) -> dict[str, Layout]:
    """The rows of the wall indices' per-sample arrays (:data:`FluidOutputs.INDEX_ARRAYS`): one
    per owned sample, keyed by its reference coordinates. Call it before the mesh moves."""
    layout = interface_layout("wall_samples", outputs.sampler.reference, 1)
    return {f"wall_indices.{name}": layout for name in outputs.INDEX_ARRAYS}
