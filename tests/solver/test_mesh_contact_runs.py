"""Mesh-mesh contact end to end: two generated cubes fall onto each other and the ground
without ever intersecting; intersecting or touching shapes at the start are refused."""

from __future__ import annotations

import pytest
from generated import write_box_msh
from iterates import watch_iterates

from ipcsim.cli import main
from ipcsim.contact.intersection import find_intersections
from ipcsim.model.build import build_model
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation


@pytest.fixture(scope="module")
def cube_mesh(tmp_path_factory):
    folder = tmp_path_factory.mktemp("mesh")
    return write_box_msh(folder / "cube.msh")


def _scene(tmp_path, cube_mesh, shapes: str, extra: str = "") -> Simulation:
    scene = tmp_path / "scene.txt"
    scene.write_text(f"shapes input 2\n{shapes}\nground 0 0\ntime 1 0.02\n{extra}")
    return scene


def test_two_cubes_stack_without_intersection(tmp_path, cube_mesh):
    scene = _scene(tmp_path, cube_mesh, f"{cube_mesh} 0.01 0.25 0.005  0 20 0  1 1 1\n"
                                        f"{cube_mesh} 0 0.005 0  0 0 0  1 1 1",
                   "stiffness 1e7 0.4\n")
    sim = Simulation(build_model(load_scene(scene)))
    mc = sim.contact.mesh
    iterate_gaps = []

    def seen(xi, evaluation):
        iterate_gaps.append(evaluation.contacts.min_distance)
        assert len(find_intersections(xi, mc.edges, mc.triangles)) == 0

    watch_iterates(sim, seen)
    contact_steps = 0
    for _ in range(40):
        row = sim.step().row
        assert row["converged"]
        contact_steps += row["contacts_point_triangle"] + row["contacts_edge_edge"] > 0
    assert contact_steps > 5  # the cubes did meet
    assert min(iterate_gaps) > 0.0
    top = sim.state.x[sim.model.vertex_shape == 0]
    bottom = sim.state.x[sim.model.vertex_shape == 1]
    # frictionless, yet centred enough to stay on top; the barrier keeps a gap below d̂
    assert 0.0 < top[:, 1].min() - bottom[:, 1].max() < sim.model.dhat


@pytest.mark.parametrize("second,fragment", [
    ("0.05 0.1 0.05  0 0 0", "intersect"),   # overlapping
    ("0 0.205 0  0 0 0", "intersect or touch"),  # exactly face to face
])
def test_intersecting_start_is_refused_naming_the_shapes(tmp_path, cube_mesh, capsys, second,
                                                        fragment):
    scene = _scene(tmp_path, cube_mesh, f"{cube_mesh} 0 0.005 0  0 0 0  1 1 1\n"
                                        f"{cube_mesh} {second}  1 1 1")
    assert main(["run", str(scene), "-o", str(tmp_path / "out"), "-q"]) == 2
    err = capsys.readouterr().err
    assert "shape 1 (cube) and shape 2 (cube)" in err and fragment in err
    assert "Traceback" not in err


def test_the_contact_hessian_is_gone_before_the_factorisation(tmp_path, cube_mesh,
                                                              monkeypatch):
    """Newton keeps no Hessian triplets past the assembly, and the assembly none past
    bucketing them: in heavy contact they are more memory than anything else it holds
    (checked when the merged matrix is built and at every solve)."""
    import weakref

    from ipcsim.kernels.algebra import assembly as kernels

    scene = _scene(tmp_path, cube_mesh, f"{cube_mesh} 0.01 0.205 0.005  0 20 0  1 1 1\n"
                                        f"{cube_mesh} 0 0.001 0  0 0 0  1 1 1",
                   "stiffness 1e7 0.4\n")
    # the sparse path: 162 DOFs would be factored dense
    monkeypatch.setattr("ipcsim.simulation.DENSE_HESSIAN_UP_TO", 0)
    sim = Simulation(build_model(load_scene(scene)))
    held = []  # weak references to the last evaluation's contact triplets

    def seen(xi, evaluation):
        held.clear()
        if evaluation.hessian is not None:
            held.extend(weakref.ref(t.vals) for t in evaluation.hessian[1] if t.size)

    watch_iterates(sim, seen)
    solve = sim.newton.linear_solver.solve
    checked = []

    def solve_checked(A, rhs):
        checked.append(len(held))
        assert all(ref() is None for ref in held)  # every triplet array was freed
        return solve(A, rhs)

    sim.newton.linear_solver.solve = solve_checked
    merge = kernels.merge_columns
    merged = []

    def merge_checked(*args):
        merged.append(len(held))
        assert all(ref() is None for ref in held)
        return merge(*args)

    monkeypatch.setattr(kernels, "merge_columns", merge_checked)
    for _ in range(5):
        sim.step()
    assert sum(checked) > 0 and sum(merged) > 0  # contact triplets were made and merged
