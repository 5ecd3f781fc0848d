"""Newton's iterations as one compiled call (kernels/terms/newton_loop.py) are the Python loop's
bit for bit: every iterate, κ, row and contact count, on two small boxes in contact with
each other and the ground (friction, Newmark with damping, prescribed vertices that CCD
stops and a pull takes over), at the iteration cap, where the line search gives up, and
where an iteration would raise (Python does it again and names the culprit), and where a
pull ends with its vertices placed on their targets."""

from __future__ import annotations

import math

from msgspec.structs import replace
import numpy as np
import pytest

import ipcsim.potentials.fused as fused_module
from ipcsim.errors import NonFiniteError
from ipcsim.kernels.terms import newton_loop as kn
from ipcsim.model.builder import build_model
from ipcsim.potentials.objective import StepObjective
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation

from generated import write_box_msh

TWO_BOXES = """shapes input 2
box.msh 0 0.0005 0  0 0 0  1 1 1
box.msh 0 0.2012 0  0 0 0  1 1 1{top}
selfFric 0.2
ground 0.3 0
time 1 0.01
{extra}
"""
DRIVEN = "  DBC -0.1 0.9 -0.1  1.1 1.1 1.1  {velocity}  0 0 0"

SCENES = {
    "backward Euler, friction": TWO_BOXES.format(top="", extra=""),
    "Newmark, damping": TWO_BOXES.format(top="", extra="timeIntegration NM\ndampingRatio 0.1"),
    "top face driven down": TWO_BOXES.format(top=DRIVEN.format(velocity="0 -1 0"), extra=""),
    "top face driven sideways": TWO_BOXES.format(top=DRIVEN.format(velocity="0.5 0 0"),
                                                 extra=""),
    # CCD stops the prescribed vertices at the ground, and a pull takes over
    "bottom face driven into the ground": """shapes input 1
box.msh 0 0.0005 0  0 0 0  1 1 1  DBC -0.1 -0.1 -0.1  1.1 0.1 1.1  0 -1 0  0 0 0
ground 0.2 0
time 1 0.01
""",
    "no mesh contact": """shapes input 1
box.msh 0 0.0005 0  0 0 0  1 1 1
ground 0.3 0
time 1 0.01
""",
    # no free DOFs: every direction is the prescribed motion, or nothing at all
    "every vertex prescribed, at rest": """shapes input 1
box.msh 0 0.5 0  0 0 0  1 1 1  DBC -0.1 -0.1 -0.1  1.1 1.1 1.1  0 0 0  0 0 0
ground 0.3 0
time 1 0.01
""",
    "every vertex prescribed, moving": """shapes input 1
box.msh 0 0.5 0  0 0 0  1 1 1  DBC -0.1 -0.1 -0.1  1.1 1.1 1.1  0.3 0 0  0 0 0
ground 0.3 0
time 1 0.01
""",
}


def simulation(tmp_path, scene: str, compiled: bool, monkeypatch) -> Simulation:
    """A simulation of ``scene`` whose Newton compiles its iterations or does not (the
    fused terms either way: 16 vertices make a dense Newton matrix)."""
    write_box_msh(tmp_path / "box.msh", cells=(1, 1, 1))
    (tmp_path / "scene.txt").write_text(scene)
    sim = Simulation(build_model(load_scene(tmp_path / "scene.txt")))
    if sim.potential.fused is None:
        sim.potential = sim.potential.fusing()
    assert sim.potential.fused is not None
    sim.compiled_newton = compiled
    return sim


@pytest.fixture
def statuses(monkeypatch):
    """The compiled iterations' statuses, call by call; ``sim.compiled_newton`` picks
    whether a simulation's Newton may compile its iterations."""
    seen = []
    call = fused_module.newton_iterations

    def spy(fused, x, span, ctx, contact, newton):
        out = call(fused, x, span, ctx, contact, newton)
        seen.append(out.status)
        if newton[1][3]:  # a pull was under way: its iterations ran compiled
            seen.append("pulling")
        return out

    monkeypatch.setattr("ipcsim.potentials.objective.fused_newton_iterations", spy)
    return seen


def step_both(compiled: Simulation, plain: Simulation, monkeypatch, steps: int = 12):
    """Step both simulations side by side; the rows of every step must be equal.
    Returns the newton.csv rows of every step."""
    rows = []
    for _ in range(steps):
        reports = []
        for sim in (compiled, plain):
            monkeypatch.setattr("ipcsim.potentials.objective.newton_available",
                                lambda on=sim.compiled_newton: on)
            reports.append(sim.step())
        assert same_rows(reports[0].newton, reports[1].newton)
        assert same_rows([reports[0].row], [reports[1].row], skip="wall_")
        rows.append(reports[0].newton)
    assert np.array_equal(compiled.state.x, plain.state.x)
    assert np.array_equal(compiled.state.v, plain.state.v)
    assert compiled.state.kappa == plain.state.kappa
    return rows


def same_rows(a, b, skip: str | None = None) -> bool:
    """Rows equal key for key, in order, value for value (NaN equal to NaN) and type."""
    if len(a) != len(b):
        return False
    for ra, rb in zip(a, b):
        keys = [k for k in ra if skip is None or not k.startswith(skip)]
        if keys != [k for k in rb if skip is None or not k.startswith(skip)]:
            return False
        for k in keys:
            u, v = ra[k], rb[k]
            if type(u) is not type(v) and not (isinstance(u, float) and isinstance(v, float)):
                return False
            if not (u == v or (isinstance(u, float) and math.isnan(u) and math.isnan(v))):
                return False
    return True


@pytest.mark.parametrize("scene", SCENES)
def test_compiled_iterations_are_the_python_loops(tmp_path, monkeypatch, statuses, scene):
    compiled, plain = (simulation(tmp_path, SCENES[scene], on, monkeypatch)
                       for on in (True, False))
    pulls = []
    start_pull = StepObjective._start_pull
    monkeypatch.setattr(StepObjective, "_start_pull",
                        lambda self, x: (pulls.append(self), start_pull(self, x))[1])
    step_both(compiled, plain, monkeypatch)
    if scene == "bottom face driven into the ground":
        # after each first iteration Python decides on a pull; one took over, and its
        # iterations ran compiled too, one call each (Python tightens or ends the pull)
        assert kn.FOLLOW_UP in statuses and any(p.revision for p in pulls)
        assert statuses.count("pulling") >= 10, statuses.count("pulling")
    elif scene == "every vertex prescribed, at rest":  # nothing to do: no line search
        assert all(r["alpha"] == 0.0 for r in plain.step().newton)
    else:
        assert statuses.count(kn.CONVERGED) >= 8  # the compiled iterations ended most steps


@pytest.mark.parametrize("scene", ["backward Euler, friction",
                                   "bottom face driven into the ground"])
def test_a_steps_end_is_counted_by_the_compiled_iterations(tmp_path, monkeypatch,
                                                           statuses, scene):
    """Where the compiled iterations end (a step's end, or a pull's next call), their
    collision set and contact count there are the ones Python's final evaluation and
    rows take: Python neither narrows the swept pairs nor counts contacts again."""
    import ipcsim.potentials.objective as objective_module
    from ipcsim.contact.setup import ContactSetup

    sim = simulation(tmp_path, SCENES[scene], True, monkeypatch)
    monkeypatch.setattr("ipcsim.potentials.objective.newton_available", lambda: True)
    calls = []
    count, narrowed = ContactSetup.count, objective_module.narrowed_collisions
    monkeypatch.setattr(ContactSetup, "count",
                        lambda self, *a: (calls.append("count"), count(self, *a))[1])
    monkeypatch.setattr(objective_module, "narrowed_collisions",
                        lambda *a: (calls.append("narrowed"), narrowed(*a))[1])
    rows = [sim.step().row for _ in range(12)]
    assert calls == [] and sum(r["contacts_total"] for r in rows) > 0  # in contact
    ended = (kn.FOLLOW_UP if scene.startswith("bottom") else kn.CONVERGED)
    assert statuses.count(ended) >= 8, sorted(set(map(str, statuses)))


def test_kappas_doubling_is_the_python_loops(tmp_path, monkeypatch, statuses):
    """κ doubles while the closest contact keeps closing in below dTol: here dTol is d̂
    itself, so that it does in a short run."""
    compiled, plain = (simulation(tmp_path, SCENES["backward Euler, friction"], on,
                                  monkeypatch) for on in (True, False))
    for sim in (compiled, plain):
        sim.stiffness = replace(sim.stiffness, eps_sq=sim.model.dhat ** 2)
    steps = step_both(compiled, plain, monkeypatch, steps=20)
    assert statuses.count(kn.CONVERGED) >= 15
    doubled = [b["kappa"] == 2.0 * a["kappa"] for rows in steps for a, b in zip(rows, rows[1:])]
    assert any(doubled)


def test_the_iteration_cap_is_the_python_loops(tmp_path, monkeypatch, statuses):
    compiled, plain = (simulation(tmp_path, SCENES["backward Euler, friction"], on,
                                  monkeypatch) for on in (True, False))
    for sim in (compiled, plain):
        sim.newton.settings = replace(sim.newton.settings, max_newton_iterations=2)
    step_both(compiled, plain, monkeypatch, steps=4)
    assert kn.ITERATION_CAP in statuses
    assert compiled.step().result.hit_iteration_cap


def test_a_line_search_that_gives_up_is_the_python_loops(tmp_path, monkeypatch, statuses):
    """A tolerance no step reaches: the line search gives up at round-off."""
    compiled, plain = (simulation(tmp_path, SCENES["backward Euler, friction"], on,
                                  monkeypatch) for on in (True, False))
    for sim in (compiled, plain):
        sim.tolerance = lambda step: 1e-300
    step_both(compiled, plain, monkeypatch, steps=3)
    assert kn.LINE_SEARCH_FAILED in statuses


def test_an_iteration_that_would_raise_is_done_again_in_python(tmp_path, monkeypatch,
                                                               statuses):
    """A non-finite velocity: the compiled iterations hand back, and Python names the
    term, as without them."""
    errors = []
    for on in (True, False):
        sim = simulation(tmp_path, SCENES["backward Euler, friction"], on, monkeypatch)
        monkeypatch.setattr("ipcsim.potentials.objective.newton_available", lambda on=on: on)
        sim.step()
        v = sim.state.v.copy()
        v[3, 1] = np.nan
        sim.state = replace(sim.state, v=v)
        with pytest.raises(NonFiniteError) as caught:
            sim.step()
        errors.append(str(caught.value))
    assert kn.HAND_BACK in statuses
    assert errors[0] == errors[1]


def test_kappas_balance_is_summed_in_index_order():
    """κ's balance and the logged gradient norm sum in index order on both sides (numpy's
    BLAS sums in blocks whose order depends on the build)."""
    from ipcsim.contact.stiffness import balanced_kappa
    from ipcsim.kernels.algebra.linalg import dot
    from ipcsim.solver.newton import _norm

    rng = np.random.default_rng(7)
    gb, gr = rng.normal(size=101), rng.normal(size=101) * 1e3
    in_order = 0.0
    for a, b in zip(gb.tolist(), gr.tolist()):
        in_order += a * b
    assert dot(gb, gr) == in_order
    squares = 0.0
    for a in gb.tolist():
        squares += a * a
    assert _norm(gb) == math.sqrt(squares)
    assert balanced_kappa(gb, gr, -np.inf, np.inf) == -in_order / squares
    assert balanced_kappa(gb, gr, 1e9, 2e9) == 1e9 and balanced_kappa(0 * gb, gr, 5.0, 6.0) == 5.0


@pytest.mark.parametrize("cells, dense", [((2, 2, 2), True), ((3, 3, 3), True),
                                          ((3, 3, 4), True), ((3, 4, 4), False)])
def test_auto_factors_dense_up_to_240_dofs_where_newton_runs_compiled(tmp_path, monkeypatch,
                                                                      cells, dense):
    """Boxes of 27, 64, 80 and 100 vertices (81, 192, 240 and 300 DOFs): dense where
    Newton's iterations run compiled up to DENSE_WITH_COMPILED_NEWTON_UP_TO, above
    DENSE_UP_TO never otherwise."""
    write_box_msh(tmp_path / "box.msh", cells=cells)
    (tmp_path / "scene.txt").write_text(SCENES["no mesh contact"])
    model = build_model(load_scene(tmp_path / "scene.txt"))
    monkeypatch.setattr("ipcsim.simulation.fused_kernels_available", lambda: True)
    monkeypatch.setattr("ipcsim.simulation.newton_available", lambda: True)
    sim = Simulation(model)
    assert (sim.linear_solver.name == "dense") == dense
    assert (sim.potential.fused is not None) == dense
    monkeypatch.setattr("ipcsim.simulation.newton_available", lambda: False)
    assert Simulation(model).linear_solver.name != "dense"


def test_the_kinematic_completion_rule_is_the_python_loops(tmp_path, monkeypatch, statuses):
    """The prescribed motion counts as done once what remains is at most 0.1 % of the
    motion at the solve's start. With that start measured 200 times too large, what
    remains at the first iteration is 0.5 % of it: still to be done, on both sides."""
    from ipcsim.solver import newton

    measured = newton._Progress

    compiled, plain = (simulation(tmp_path, SCENES["top face driven sideways"], on,
                                  monkeypatch) for on in (True, False))
    made = []  # the motion at each solve's start

    def progress(prescribed, tol):
        made.append(prescribed)
        return measured(200.0 * prescribed, tol)

    monkeypatch.setattr(newton, "_Progress", progress)
    steps = step_both(compiled, plain, monkeypatch, steps=4)
    assert statuses.count(kn.CONVERGED) >= 3 and min(made) > 0.0  # there was motion
    assert all(rows[0]["alpha"] > 0.0 for rows in steps)  # and it was still taken


PRESS = """shapes input 2
box.msh 0 0.205 0  0 0 0  1 1 1  DBC -0.1 0.9 -0.1  1.1 1.1 1.1  0 -0.6 0  0 0 0
box.msh 0 0 0  0 0 0  1 1 1  DBC -0.1 -0.1 -0.1  1.1 1.1 1.1  0 0 0  0 0 0
time 0.15 0.05
stiffness 1e5 0.4
turnOffGravity
"""


def test_a_pull_that_ends_by_placement_is_the_same_compiled(tmp_path, monkeypatch, statuses,
                                                            pulls_end_by_placement):
    """A top face pressed onto a fixed box, with pulls that end only in their tail, where
    the pulled vertices are placed on their targets: the compiled iterations go on from
    the placed x exactly as the Python loop does."""
    placed = pulls_end_by_placement
    compiled, plain = (simulation(tmp_path, PRESS, on, monkeypatch) for on in (True, False))
    step_both(compiled, plain, monkeypatch, steps=3)
    assert sum(p is not None for p in placed) >= 2  # in both simulations
    assert "pulling" in statuses
