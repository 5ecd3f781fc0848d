"""Shared data for the scene tests (imported by conftest.py and the test modules)."""

from __future__ import annotations

from pathlib import Path

from examples import example_scripts, extra_scripts_with_meshes  # noqa: F401  (re-exported)

MESHES = ("meshes/cube.msh", "meshes/tri.obj", "meshes/edge.seg", "meshes/cloud.pt",
          "meshes/plane.obj", "meshes/fallback.obj", "meshes/tg.node", "meshes/tg.ele",
          "status42")

# A scene that uses nearly every keyword and shape extra.
RICH_SCENE = """\
# every feature at once
energy FCR
time 2 0.01
density 1200
stiffness 2e5 0.3
timeIntegration NM 0.3 0.6
dampingStiff 0.5
warmStart 2
selfFric 0.2
fricIterAmt 3
tuning 6
1e5
0.01
1e-3
1e-8
1e-3
1e-3
tol 3
1e-2
1e-3 1e-4
kappaMinMultiplier 1e10
DBCTimeRange 0.5 3
NBCTimeRange 1
handleRatio 0.02
size 2
rotateModel 0 0 1 30
playBackSpeed 0.5
appendStr run1
dHatAbs 1e-4
epsvAbs 2e-3
linearSolver CHOLMOD
restart status42
ground 0.1 -1
halfSpace 0 -2 0  1 1 0  50 0.3
meshCO meshes/plane.obj 0 -1 0 10 50 0.2 rotate 0 0 5
shapes input 3
meshes/cube.msh 0 1 0  0 0 0  1 1 1  material 900 3e5 0.35 initVel 0 -1 0 0 90 0 \\
    DBC -0.1 -0.1 -0.1  0.1 1.1 0.1  0 0 0  0 0 0  0 2.5 \\
    NBC 0.9 -0.1 0.9  1.1 1.1 1.1  5 0 5  1
meshes/tri.obj 0 3 0  0 0 90  2 2 2  linearVelocity 0 -1 0 angularVelocity 0 10 0
meshes/edge.seg 0 5 0  0 0 0  1 1 1  meshSeq meshes
shapeMatrix input 2 1 2 0 10 0
meshes/cube.msh 1.5 1 1.5  0 0 0  1 1 1 material 1000 1e5 0.4
"""


def make_mesh_folder(root: Path) -> Path:
    for name in MESHES:
        p = root / name
        p.parent.mkdir(parents=True, exist_ok=True)
        p.write_text("")
    return root


# A 2D scene that uses every 2D key (TOML only: the text format has no 2D form).
RICH_2D_SCENE = """\
[scene]
dimension = 2
gravity_acceleration = [0.0, -9.81]
size = 2.0
[material]
density = 1000
node_masses = "uniform"
[contact]
kappa = 1e5
dhat_abs = 0.01
barrier = "lecture"
self_friction = 0.2
[[shapes]]
kind = "rectangle"
size = [1.0, 1.0]
resolution = [4, 4]
spring_stiffness = 2e4
translation = [0.5, 0.25]
rotation_deg = 30
scale = [2.0, 1.0]
init_velocity = { linear = [1.0, -1.0], angular_deg = 5 }
[[shapes.dbc]]
box_min = [0.0, 0.9]
box_max = [1.0, 1.0]
linear_velocity = [0.0, -0.5]
angular_velocity_deg = 10
time_range = [0.0, 2.0]
[[shapes.nbc]]
box_min = [0.0, 0.0]
box_max = [0.5, 0.5]
acceleration = [3.0, 0.0]
[[shapes]]
path = "meshes/cube.msh"
translation = [0.0, 3.0]
matrix = { counts = [2, 1], spacing = [2.0, 0.0] }
[[shapes]]
path = "meshes/edge.seg"
linear_velocity = [1.0, 0.0]
angular_velocity_deg = 3
[[planes]]
kind = "ground"
height = -1.0
friction = 0.11
[[planes]]
kind = "halfSpace"
origin = [0.0, 0.6]
normal = [0.0, -1.0]
velocity = [0.0, -0.5]
limit = [0.0, -0.6]
"""
