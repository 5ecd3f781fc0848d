"""The terms evaluated together (potentials/kernel_data.py, kernels/terms/all_terms.py)
give the terms' own numbers, bit for bit: every value, every gradient and the dense
Newton matrix with its coupling, on two small boxes in contact with each other and the
ground (friction, damping, a pull, prescribed vertices, the penalty baseline), and whole
runs with the Hessian added in one call or term by term."""

from __future__ import annotations

from msgspec.structs import replace
import numpy as np
import pytest

from ipcsim.contact.collisions import build_collisions, swept_collisions
from ipcsim.kernels.terms import all_terms as kt
from ipcsim.model.build import build_model
from ipcsim.potentials.base import Triplets
from ipcsim.potentials.boundary_pull import BoundaryPull
from ipcsim.potentials.incremental import IncrementalPotential, WeightedTerm
from ipcsim.potentials.kernel_data import TermData
from ipcsim.potentials.penalty_contact import PenaltyMeshContact, PenaltyPlaneContact
from ipcsim.potentials.step_problem import StepProblem
from ipcsim.scene import load_scene
from ipcsim.simulation import Simulation
from ipcsim.solver.assembly import DenseAssembler

from generated import write_box_msh

SCENE = """shapes input 2
box.msh 0 0.0005 0  0 0 0  1 1 1
box.msh 0 0.2012 0  0 0 0  1 1 1
selfFric 0.2
ground 0.3 0
time 1 0.01
{extra}
"""

VARIANTS = {
    "backward Euler, friction": "",
    "Newmark, damping": "timeIntegration NM\ndampingRatio 0.1",
}


def simulation(tmp_path, text: str) -> Simulation:
    write_box_msh(tmp_path / "box.msh", cells=(1, 1, 1))
    (tmp_path / "scene.txt").write_text(text)
    return Simulation(build_model(load_scene(tmp_path / "scene.txt")))


def termwise(potential: IncrementalPotential, x, ctx, kappa):
    """Each term on its own: values, gradients, ∇E at κ and the Hessian parts."""
    values = tuple(float(t.term.value(x, ctx)) for t in potential.terms)
    gradients = [t.term.gradient(x, ctx) for t in potential.terms]
    g = np.zeros(x.size)
    for t, gi in zip(potential.terms, gradients):
        g += t.factor(kappa) * gi
    static, dynamic = [], []
    for t in potential.terms:
        h = t.term.hessian(x, ctx).scaled(t.factor(kappa))
        (static if t.term.constant_pattern else dynamic).append(h)
    return values, gradients, g, (static, dynamic)


def assert_same_numbers(potential: IncrementalPotential, x, ctx, kinematic, kappa):
    """Values, gradients, the energy at κ and the dense matrix with its coupling."""
    data = potential.kernel.data(ctx)
    together = potential.evaluate(x, ctx, data, 2)
    values, gradients, g, parts = termwise(potential, x, ctx, kappa)
    assert together.values == values
    for kind, gi in zip(potential.kernel.kinds, gradients):
        assert np.array_equal(together.gradients[kind], gi)
    assert np.array_equal(together.gradient(kappa), g)
    free_dofs = ~np.repeat(kinematic, 3)
    free_index = np.full(free_dofs.size, -1, dtype=np.int64)
    free_index[free_dofs] = np.arange(int(free_dofs.sum()))
    p = np.zeros(x.size)
    p[~free_dofs] = np.random.default_rng(3).normal(size=int((~free_dofs).sum()))
    n_free = int(free_dofs.sum())
    A_terms, coupling_terms = DenseAssembler().assemble(*parts, free_index, n_free, p)
    one_call = potential.hessian(x, ctx, data, kappa, dense=True)
    A_one, coupling_one = DenseAssembler().assemble(*one_call, free_index, n_free, p)
    assert np.array_equal(A_terms, A_one) and np.array_equal(coupling_terms, coupling_one)
    assert np.count_nonzero(A_terms) > 0


def _settled(tmp_path, variant):
    sim = simulation(tmp_path, SCENE.format(extra=VARIANTS[variant]))
    for _ in range(8):  # the boxes settle onto each other and the ground
        sim.step()
    problem, _ = sim.problem(sim.state)
    x = sim.state.x + 1e-6 * np.random.default_rng(1).normal(size=sim.state.x.shape)
    kinematic = np.zeros(len(x), dtype=bool)
    kinematic[[0, 5, 11]] = True  # prescribed vertices: their columns go to the coupling
    return sim, problem, x, kinematic


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_number_is_the_terms_own(tmp_path, variant):
    sim, problem, x, kinematic = _settled(tmp_path, variant)
    ctx, contact = problem.ctx, sim.contact
    at_x = replace(ctx, collisions=build_collisions(contact.mesh, x, contact.dhat))
    assert at_x.collisions.may_be_active(contact.dhat)  # the boxes touch
    assert ctx.friction is not None and ctx.friction.count > 0
    kappa = 3.0 * problem.stiffness.kappa
    assert_same_numbers(sim.potential, x, at_x, kinematic, kappa)
    # a line search's set: swept over a motion, without distances
    swept = replace(ctx, collisions=swept_collisions(contact.mesh, x, x + 1e-4, contact.dhat))
    assert_same_numbers(sim.potential, x, swept, kinematic, kappa)
    # a pull of the top box's prescribed vertices, with multipliers
    top = np.arange(8, 16)
    pull = BoundaryPull(top, sim.model.mass[top].copy(), x[top] + 1e-3, x[top].copy())
    pull = pull.stiffer().with_updated_multipliers(x)
    assert_same_numbers(sim.potential.with_term(WeightedTerm(pull)), x, at_x, kinematic,
                        kappa)


def test_the_penalty_baselines_numbers_are_its_terms_own(tmp_path):
    sim, problem, x, kinematic = _settled(tmp_path, "backward Euler, friction")
    contact = sim.contact
    planes = next(t.term.planes for t in sim.potential.terms if t.term.name == "plane contact")
    kept = tuple(t for t in sim.potential.terms if not t.barrier)
    penalty = IncrementalPotential(kept + (WeightedTerm(PenaltyPlaneContact(planes, 2e-3, 1e4)),
                                           WeightedTerm(PenaltyMeshContact(2e-3, 1e4))))
    # the boxes 1 mm into each other: the penalty pairs act
    y = x.copy()
    y[8:] -= [0.0, 0.0022, 0.0]
    at_y = replace(problem.ctx, collisions=build_collisions(contact.mesh, y, 4e-3))
    values, *_ = termwise(penalty, y, at_y, 1.0)
    assert values[-1] > 0.0 and values[-2] > 0.0
    assert_same_numbers(penalty, y, at_y, kinematic, 1.0)


def test_each_kind_comes_once(tmp_path):
    sim = simulation(tmp_path, SCENE.format(extra=""))
    terms = sim.potential.terms
    assert set(TermData.of(terms).kinds) <= set(range(kt.N_KINDS))
    with pytest.raises(ValueError, match="one term of each kind"):
        TermData.of(terms + (terms[0],))


DRIVEN = """shapes input 2
box.msh 0 0.0005 0  0 0 0  1 1 1
box.msh 0 0.2012 0  0 0 0  1 1 1  DBC -0.1 0.9 -0.1  1.1 1.1 1.1  {velocity}  0 0 0
selfFric 0.2
ground 0.3 0
time 1 0.01
"""

PRESCRIBED = {
    # the free vertices of the top box pressed onto the bottom one: CCD cuts the steps
    "top face driven down": DRIVEN.format(velocity="0 -1 0"),
    # the prescribed vertices land exactly on their targets
    "top face driven sideways": DRIVEN.format(velocity="0.5 0 0"),
    # CCD stops the prescribed vertices at the ground, and the pull takes over
    "bottom face driven into the ground": """shapes input 1
box.msh 0 0.0005 0  0 0 0  1 1 1  DBC -0.1 -0.1 -0.1  1.1 0.1 1.1  0 -1 0  0 0 0
ground 0.2 0
time 1 0.01
""",
}


@pytest.mark.parametrize("variant", [*VARIANTS, *PRESCRIBED])
def test_runs_are_the_same_with_the_hessian_in_one_call_or_term_by_term(tmp_path, variant,
                                                                         monkeypatch):
    """Whole steps: the terms' Hessians added into the dense matrix in one call against
    each term's own triplets added one by one."""
    text = SCENE.format(extra=VARIANTS[variant]) if variant in VARIANTS else PRESCRIBED[variant]
    one_call, termwise_sim = simulation(tmp_path, text), simulation(tmp_path, text)
    assert one_call.one_call_hessian and one_call.linear_solver.dense
    termwise_sim.one_call_hessian = False
    pulls = []
    start_pull = StepProblem._start_pull
    monkeypatch.setattr(StepProblem, "_start_pull",
                        lambda self, x: (pulls.append(start_pull(self, x)), pulls[-1])[1])
    alphas = []
    for _ in range(12):
        reports = one_call.step(), termwise_sim.step()
        assert reports[0].newton == reports[1].newton  # every iteration's α, E, contacts
        alphas += [row["alpha"] for row in reports[0].newton]
    assert np.array_equal(one_call.state.x, termwise_sim.state.x)
    assert np.array_equal(one_call.state.v, termwise_sim.state.v)
    if variant == "top face driven down":
        assert min(alphas) < 0.5  # CCD cut steps: the next sweep goes over [0, 2α] first
    if variant == "bottom face driven into the ground":
        assert any(p.pull is not None for p in pulls)  # a pull acted


def test_the_one_call_hessian_is_added_as_one_dense_part(tmp_path):
    sim = simulation(tmp_path, SCENE.format(extra=""))
    problem, start = sim.problem(sim.state)
    _, ev = problem.evaluate(start, 2)
    static, dynamic = ev.hessian
    assert len(static) == 1 and dynamic == [] and not isinstance(static[0], Triplets)


def test_a_steps_final_energy_comes_from_its_line_search(tmp_path, monkeypatch):
    """The terms' values at the point a step ends are the line search's: Newton's final
    evaluation does not compute them again (nor, so, do the logs' energies differ)."""
    sim = simulation(tmp_path, SCENE.format(extra=VARIANTS["backward Euler, friction"]))
    calls = []
    values = kt.term_values
    monkeypatch.setattr(kt, "term_values", lambda *a: (calls.append(1), values(*a))[1])
    rows = [sim.step().row for _ in range(10)]
    assert len(calls) == 0
    assert all(np.isfinite(r["energy"]) and r["elastic_energy"] >= 0.0 for r in rows)


def test_an_evaluations_energy_sums_each_terms_value_once(tmp_path, monkeypatch):
    """The values ``evaluate(point, 0)`` reads are those its energy and the logs read
    after it: one call of the values' kernel."""
    sim = simulation(tmp_path, SCENE.format(extra=VARIANTS["backward Euler, friction"]))
    calls = []
    values = kt.term_values
    monkeypatch.setattr(kt, "term_values", lambda *a: (calls.append(1), values(*a))[1])
    problem, start = sim.problem(sim.state)
    _, evaluation = problem.evaluate(start, 0)
    assert np.isfinite(evaluation.energy) and evaluation.values.value_of("elasticity") >= 0.0
    assert evaluation.values.value_of("friction") is not None
    assert len(calls) == 1
