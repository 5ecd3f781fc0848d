"""The terms evaluated together (potentials/fused.py) give the terms' own numbers, bit for
bit: every value, every gradient and the dense Newton matrix with its coupling, on
two small boxes in contact with each other and the ground (friction, damping, a pull,
prescribed vertices), and whole runs."""

from __future__ import annotations

from msgspec.structs import replace
import numpy as np
import pytest

from ipcsim.contact.collisions import build_collisions, swept_collisions
from ipcsim.model.builder import build_model
from ipcsim.potentials.base import Triplets
from ipcsim.potentials.boundary_pull import BoundaryPull
from ipcsim.potentials.fused import FusedTerms
from ipcsim.potentials.incremental import IncrementalPotential, WeightedTerm
from ipcsim.potentials.objective import StepObjective
from ipcsim.potentials.penalty_contact import PenaltyPlaneContact
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


def simulation(tmp_path, extra: str) -> Simulation:
    write_box_msh(tmp_path / "box.msh", cells=(1, 1, 1))
    (tmp_path / "scene.txt").write_text(SCENE.format(extra=extra))
    return fused_sim(Simulation(build_model(load_scene(tmp_path / "scene.txt"))))


def fused_sim(sim: Simulation) -> Simulation:
    """``sim`` with its terms fused (as a run does where the fused kernels were compiled
    at install: 16 vertices make a dense Newton matrix)."""
    if sim.potential.fused is None:
        sim.potential = sim.potential.fusing()
    assert sim.potential.fused is not None
    return sim


def termwise(potential: IncrementalPotential) -> IncrementalPotential:
    return IncrementalPotential(potential.terms)


def assert_same_numbers(fused: IncrementalPotential, x, ctx, kinematic, kappa):
    """Values, gradients, the energy at κ and the dense matrix with its coupling."""
    plain = termwise(fused)
    a, b = plain.evaluate(x, ctx, 2), fused.evaluate(x, ctx, 2)
    assert a.values == b.values
    for ga, gb in zip(a.gradients, b.gradients):
        assert np.array_equal(ga, gb)
    assert np.array_equal(a.gradient(kappa), b.gradient(kappa))
    assert plain.value(x, ctx, kappa) == fused.value(x, ctx, kappa) == b.energy(kappa)
    free_dofs = ~np.repeat(kinematic, 3)
    free_index = np.full(free_dofs.size, -1, dtype=np.int64)
    free_index[free_dofs] = np.arange(int(free_dofs.sum()))
    p = np.zeros(x.size)
    p[~free_dofs] = np.random.default_rng(3).normal(size=int((~free_dofs).sum()))
    n_free = int(free_dofs.sum())
    A_plain, coupling_plain = DenseAssembler().assemble(*a.hessian(kappa), free_index,
                                                        n_free, p)
    A_fused, coupling_fused = DenseAssembler().assemble(*b.hessian(kappa), free_index,
                                                        n_free, p)
    assert np.array_equal(A_plain, A_fused) and np.array_equal(coupling_plain, coupling_fused)
    assert np.count_nonzero(A_plain) > 0


@pytest.mark.parametrize("variant", VARIANTS)
def test_every_number_is_the_terms_own(tmp_path, variant):
    sim = simulation(tmp_path, VARIANTS[variant])
    for _ in range(8):  # the boxes settle onto each other and the ground
        sim.step()
    objective = sim.objective(sim.state)
    ctx, contact = objective.ctx, sim.contact
    x = sim.state.x + 1e-6 * np.random.default_rng(1).normal(size=sim.state.x.shape)
    at_x = replace(ctx, collisions=build_collisions(contact.mesh, x, contact.dhat))
    assert at_x.collisions.may_be_active(contact.dhat)  # the boxes touch
    assert ctx.friction is not None and ctx.friction.count > 0
    kinematic = np.zeros(len(x), dtype=bool)
    kinematic[[0, 5, 11]] = True  # prescribed vertices: their columns go to the coupling
    kappa = 3.0 * objective.stiffness.kappa
    assert_same_numbers(sim.potential, x, at_x, kinematic, kappa)
    # a line search's set: swept over a motion, without distances
    swept = replace(ctx, collisions=swept_collisions(contact.mesh, x, x + 1e-4, contact.dhat))
    assert_same_numbers(sim.potential, x, swept, kinematic, kappa)
    # a pull of the top box's prescribed vertices, with multipliers
    top = np.arange(8, 16)
    pull = BoundaryPull(top, sim.model.mass[top].copy(), x[top] + 1e-3, x[top].copy())
    pull = pull.stiffer().with_updated_multipliers(x)
    pulled = sim.potential.with_term(WeightedTerm(pull))
    assert pulled.fused is not None
    assert_same_numbers(pulled, x, at_x, kinematic, kappa)


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
def test_runs_are_the_same_with_and_without_fusing(tmp_path, monkeypatch, variant):
    """Whole steps: the fused terms and the fused line search against the terms one by
    one and the line search in Python."""
    if variant in VARIANTS:
        fused, plain = (simulation(tmp_path, VARIANTS[variant]) for _ in range(2))
    else:
        write_box_msh(tmp_path / "box.msh", cells=(1, 1, 1))
        (tmp_path / "scene.txt").write_text(PRESCRIBED[variant])
        fused, plain = (fused_sim(Simulation(build_model(load_scene(tmp_path / "scene.txt"))))
                        for _ in range(2))
    plain.potential = termwise(plain.potential)
    assert fused.potential.fused is not None and plain.potential.fused is None
    pulls = []
    start_pull = StepObjective._start_pull
    monkeypatch.setattr(StepObjective, "_start_pull",
                        lambda self, x: (pulls.append(self), start_pull(self, x))[1])
    alphas = []
    for _ in range(12):
        reports = fused.step(), plain.step()
        assert reports[0].newton == reports[1].newton  # every iteration's α, E, contacts
        alphas += [row["alpha"] for row in reports[0].newton]
    assert np.array_equal(fused.state.x, plain.state.x)
    assert np.array_equal(fused.state.v, plain.state.v)
    if variant == "top face driven down":
        assert min(alphas) < 0.5  # CCD cut steps: the next sweep goes over [0, 2α] first
    if variant == "bottom face driven into the ground":
        assert any(p.revision for p in pulls)  # a pull acted


def test_a_term_without_a_fused_form_keeps_the_terms_apart(tmp_path):
    sim = simulation(tmp_path, "")
    terms = sim.potential.terms
    planes = next(t.term.planes for t in terms if t.term.name == "plane contact")
    penalty = WeightedTerm(PenaltyPlaneContact(planes, 1e-3, 1e4))
    assert FusedTerms.of(terms + (penalty,)) is None
    assert FusedTerms.of(terms + (terms[0],)) is None  # a kind twice
    assert sim.potential.with_term(penalty).fused is None


def test_runs_fuse_only_where_the_fused_kernels_were_compiled_at_install(tmp_path,
                                                                       monkeypatch):
    write_box_msh(tmp_path / "box.msh", cells=(1, 1, 1))
    (tmp_path / "scene.txt").write_text(SCENE.format(extra=""))
    model = build_model(load_scene(tmp_path / "scene.txt"))
    monkeypatch.setattr("ipcsim.simulation.fused_kernels_available", lambda: True)
    assert Simulation(model).potential.fused is not None
    monkeypatch.setattr("ipcsim.simulation.fused_kernels_available", lambda: False)
    assert Simulation(model).potential.fused is None


def test_the_fused_hessian_is_added_as_one_dense_part(tmp_path):
    sim = simulation(tmp_path, "")
    objective = sim.objective(sim.state)
    static, dynamic = objective.evaluate(sim.state.x, 2).hessian
    assert len(static) == 1 and dynamic == [] and not isinstance(static[0], Triplets)


@pytest.mark.parametrize("compiled", [True, False], ids=["compiled iterations", "python loop"])
def test_a_steps_final_energy_comes_from_its_line_search(tmp_path, monkeypatch, compiled):
    """The terms' values at the point a step ends are the line search's: Newton's final
    evaluation does not compute them again (nor, so, do the logs' energies differ). Both
    where the iterations run compiled (16 vertices) and where Python runs them with the
    fused line search (as during a pull)."""
    monkeypatch.setattr("ipcsim.potentials.objective.newton_available", lambda: compiled)
    sim = simulation(tmp_path, VARIANTS["backward Euler, friction"])
    calls = []
    values = FusedTerms.values
    monkeypatch.setattr(FusedTerms, "values",
                        lambda self, x, ctx: (calls.append(1), values(self, x, ctx))[1])
    rows = [sim.step().row for _ in range(10)]
    assert len(calls) == 0
    assert all(np.isfinite(r["energy"]) and r["elastic_energy"] >= 0.0 for r in rows)


def test_an_evaluations_energy_sums_each_terms_value_once(tmp_path, monkeypatch):
    """Where the terms are evaluated one by one (a scene too large to fuse), the values
    ``evaluate(x, 0)`` reads are those its energy and the logs read after it: Newton's
    final evaluation of each step computes each term once."""
    sim = simulation(tmp_path, VARIANTS["backward Euler, friction"])
    sim.potential = termwise(sim.potential)
    elasticity = sim.potential.term("elasticity")
    calls = []
    value = type(elasticity).value
    monkeypatch.setattr(type(elasticity), "value",
                        lambda self, x, ctx: (calls.append(1), value(self, x, ctx))[1])
    evaluation = sim.objective(sim.state).evaluate(sim.state.x, 0)
    assert np.isfinite(evaluation.energy) and evaluation.values.value_of("elasticity") >= 0.0
    assert len(calls) == 1
