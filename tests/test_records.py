"""records.replaced: the same record dataclasses.replace makes."""

import dataclasses

import numpy as np
import pytest

from ipcsim.contact.stiffness import BarrierStiffness
from ipcsim.potentials.base import StepContext
from ipcsim.records import replaced


@dataclasses.dataclass(frozen=True, eq=False)
class _Plain:
    a: np.ndarray
    b: float = 1.0
    c: tuple = ()


@dataclasses.dataclass(frozen=True)
class _Checked:
    a: float

    def __post_init__(self):
        if self.a < 0:
            raise ValueError("a < 0")


def test_same_fields_as_dataclasses_replace():
    a = np.arange(3.0)
    r = _Plain(a, 2.0, (1,))
    for changes in ({}, {"b": 5.0}, {"a": a[::-1], "c": (2, 3)}):
        new, ref = replaced(r, **changes), dataclasses.replace(r, **changes)
        assert type(new) is _Plain and new is not r
        for f in dataclasses.fields(_Plain):
            assert getattr(new, f.name) is getattr(ref, f.name)
    assert r.b == 2.0 and r.c == (1,)  # the old record is untouched
    with pytest.raises(dataclasses.FrozenInstanceError):
        replaced(r, b=3.0).b = 4.0


def test_unknown_field_is_refused_as_replace_refuses_it():
    with pytest.raises(TypeError):
        replaced(_Plain(np.zeros(1)), d=1.0)


def test_post_init_still_runs():
    assert replaced(_Checked(1.0), a=2.0).a == 2.0
    with pytest.raises(ValueError, match="a < 0"):
        replaced(_Checked(1.0), a=-1.0)


@dataclasses.dataclass(frozen=True)
class _Derived:
    a: float
    b: list = dataclasses.field(init=False, default_factory=list)


def test_a_field_outside_init_is_made_anew_as_replace_makes_it():
    r = _Derived(1.0)
    r.b.append("old")
    new = replaced(r, a=2.0)
    assert new.a == 2.0 and new.b == [] and r.b == ["old"]


def test_the_step_records():
    ctx = StepContext(x_start=np.zeros((2, 3)), dhat=1e-3)
    new = replaced(ctx, collisions="set")
    assert new.collisions == "set" and new.dhat == 1e-3 and ctx.collisions is None
    k = BarrierStiffness(kappa=1.0, kappa_min=0.5, kappa_max=2.0, eps_sq=0.01)
    assert replaced(k, kappa=2.0) == dataclasses.replace(k, kappa=2.0)
    assert k.kappa == 1.0
