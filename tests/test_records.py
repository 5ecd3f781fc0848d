"""The records: frozen msgspec Structs, replaced rather than written to; ``ByMeaning``
compares and hashes by what a value means, not where it was written."""

from pathlib import Path

import msgspec
import numpy as np
import pytest

import ipcsim.model.model as model_module
import ipcsim.scene.spec as spec_module
from ipcsim.contact.stiffness import BarrierStiffness
from ipcsim.model.model import DirichletSet, MeshSequence
from ipcsim.potentials.base import StepContext
from ipcsim.records import ByMeaning
from ipcsim.scene.spec import PlaneSpec, SceneSpec, ShapeSpec


def test_a_replaced_step_record_is_new_and_the_old_one_untouched():
    ctx = StepContext(x_start=np.zeros((2, 3)), dhat=1e-3)
    new = msgspec.structs.replace(ctx, collisions="set")
    assert new.collisions == "set" and new.dhat == 1e-3 and ctx.collisions is None
    assert new.x_start is ctx.x_start  # a shallow copy: arrays are shared, not copied
    k = BarrierStiffness(kappa=1.0, kappa_min=0.5, kappa_max=2.0, eps_sq=0.01)
    assert msgspec.structs.replace(k, kappa=2.0).kappa == 2.0 and k.kappa == 1.0
    with pytest.raises(AttributeError):
        k.kappa = 3.0
    with pytest.raises(TypeError):
        msgspec.structs.replace(k, no_such_field=1.0)


def test_post_init_runs_on_replace():
    s = MeshSequence(0, 0, 4, Path("seq"), "obj")
    d = msgspec.structs.replace(DirichletSet(np.array([3, 1, 3])), vertices=[5, 2, 5])
    assert d.vertices.tolist() == [2, 5] and not d.vertices.flags.writeable
    assert msgspec.structs.replace(s, stop=5).stop == 5


def test_equal_by_meaning_whatever_the_line_or_the_path_as_written(tmp_path):
    a = ShapeSpec(tmp_path / "a.msh", path="a.msh", line=3)
    b = ShapeSpec(tmp_path / "a.msh", path="./a.msh", line=7)
    assert a == b and hash(a) == hash(b)
    assert a != ShapeSpec(tmp_path / "a.msh", translation=(1.0, 0.0, 0.0), line=3)
    scene = SceneSpec(shapes=(a,), planes=(PlaneSpec("ground", (0, 0, 0), (0, 1, 0), line=2),),
                      source=tmp_path / "x.txt", warnings=("w",), key_lines={"dt": 4})
    same = SceneSpec(shapes=(b,), planes=(PlaneSpec("ground", (0, 0, 0), (0, 1, 0)),))
    assert scene == same and hash(scene) == hash(same) and {scene: 1}[same] == 1
    assert scene != msgspec.structs.replace(same, dt=0.01)
    assert scene != "not a scene"
    assert MeshSequence(0, 0, 4, Path("s"), "obj", line=1) == \
        MeshSequence(0, 0, 4, Path("s"), "obj", line=9)


def test_every_provenance_field_is_a_field():
    for module in (spec_module, model_module):
        for cls in vars(module).values():
            if isinstance(cls, type) and issubclass(cls, ByMeaning) and cls is not ByMeaning:
                assert cls.provenance and set(cls.provenance) <= set(cls.__struct_fields__), cls
                assert cls.__struct_config__.frozen, cls


def test_same_bits_is_array_equal_where_the_bits_say_it():
    from ipcsim.records import same_bits

    x = np.arange(12.0).reshape(4, 3)
    assert same_bits(x, x.copy())
    assert same_bits(x[:, :2], np.ascontiguousarray(x[:, :2]))  # views compare by value
    y = x.copy()
    y[2, 1] = np.nextafter(y[2, 1], np.inf)
    assert not same_bits(x, y)
    assert not same_bits(x, x.reshape(3, 4))  # same bits, another shape
    assert not same_bits(x, x.astype(np.float32))
    assert not same_bits(np.zeros(3, bool), np.zeros(3, np.uint8))
    mask = np.array([True, False, True])
    assert same_bits(mask, mask.copy()) and not same_bits(mask, ~mask)
    # equal values in other bits only miss the cache
    assert not same_bits(np.array([0.0]), np.array([-0.0]))
