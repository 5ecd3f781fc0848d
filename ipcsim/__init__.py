"""ipcsim: Incremental Potential Contact simulation driven by scene files.

The Python API (docs/python-api.md)::

    spec = ipcsim.load_scene("drop.toml", overrides={"time.dt": 0.01})
    model = ipcsim.build_model(spec)
    sim = ipcsim.Simulation(model)
    report = sim.step()              # one time step; report.row is its steps.csv row
    sim.state.positions              # (n, 3) m, read-only
    ipcsim.run(spec, "output/drop")  # what `ipcsim run` does

Names are imported on first use, so ``import ipcsim`` (and the command line's start-up)
does not pay for numba until a simulation is built.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

# public name -> module that defines it
_EXPORTS = {
    "load_scene": "ipcsim.scene",
    "save_scene": "ipcsim.scene",
    "SceneSpec": "ipcsim.scene.spec",
    "build_model": "ipcsim.model.build",
    "Model": "ipcsim.model.model",
    "Simulation": "ipcsim.simulation",
    "State": "ipcsim.simulation",
    "StepReport": "ipcsim.simulation",
    "run": "ipcsim.runner",
    "RunResult": "ipcsim.runner",
    "Reporter": "ipcsim.runner",
    "IpcsimError": "ipcsim.errors",
    "ArgumentError": "ipcsim.errors",
    "SceneError": "ipcsim.errors",
    "MeshError": "ipcsim.errors",
    "SolverError": "ipcsim.errors",
    "OutputError": "ipcsim.errors",
    "RunFailed": "ipcsim.errors",
    "RunInterrupted": "ipcsim.errors",
}

__all__ = ["__version__", *_EXPORTS]


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'ipcsim' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
