"""Offscreen pictures of a run: one PNG per frame, optionally an animated GIF or MP4.

Reads only the output folder: ``frames/frame_*.vtu`` (positions, ``body_id``,
``velocity``, ``kinematic``), ``frames/series.pvd`` (frame times) and ``scene.toml``
(analytic planes, drawn as finite tiles). The surface drawn is the boundary of the tets
plus the triangle cells, built once from the first frame (connectivity never changes), so
each frame only swaps the positions.

Rendering needs no display: pyvista renders off screen; on Linux without X the VTK
wheels fall back from X to EGL (or OSMesa), and the warning VTK prints about the missing
X server is silenced while the window is made.
"""

from __future__ import annotations

import math
import re
from pathlib import Path

from msgspec import Struct
import numpy as np

from ..errors import IpcsimError
from ..atomic import atomic_path
from .vtk import FRAMES_DIR, SERIES_NAME, FrameError, frame_file_name, read_frame, read_series

__all__ = [
    "OBSTACLE_RGB",
    "PALETTE",
    "RenderError",
    "RenderOptions",
    "RunFrames",
    "FrameRenderer",
    "LiveRenderer",
    "body_rgb",
    "load_run_frames",
    "parse_frame_range",
    "render_run",
]

_FRAME_RE = re.compile(r"^frame_(\d+)\.vtu$")

# Tableau 10: distinct hues, so bodies stay distinguishable under shading.
PALETTE = np.array([
    (31, 119, 180), (255, 127, 14), (44, 160, 44), (214, 39, 40), (148, 103, 189),
    (140, 86, 75), (227, 119, 194), (188, 189, 34), (23, 190, 207), (127, 127, 127),
], dtype=np.uint8)
OBSTACLE_RGB = (150, 150, 150)
PLANE_RGB = (205, 205, 200)


class RenderError(IpcsimError):
    """A run that cannot be rendered, or options that make no sense."""


def body_rgb(body: int) -> tuple[int, int, int]:
    """Palette colour of a simulated body (cycles after 10 bodies)."""
    return tuple(int(c) for c in PALETTE[int(body) % len(PALETTE)])


class RenderOptions(Struct):
    every: int = 1
    frames: tuple[int | None, int | None] = (None, None)  # step range [a, b)
    gif: bool = False
    mp4: bool = False
    field: str = "none"  # "none" | "velocity"
    azimuth: float = 30.0  # degrees about +y; 0 looks along -z (x to the right)
    elevation: float = 20.0  # degrees above the horizontal
    zoom: float = 1.0
    size: tuple[int, int] = (800, 600)
    output: Path | None = None  # default <run>/render


def parse_frame_range(text: str) -> tuple[int | None, int | None]:
    """``A:B`` -> steps A <= step < B; either end may be left out (``10:``, ``:50``)."""
    m = re.fullmatch(r"\s*(\d*)\s*:\s*(\d*)\s*", text or "")
    if not m:
        raise RenderError(f"--frames expects A:B (frame step numbers, B excluded), got {text!r}")
    a = int(m.group(1)) if m.group(1) else None
    b = int(m.group(2)) if m.group(2) else None
    if a is not None and b is not None and b <= a:
        raise RenderError(f"--frames {text}: the range is empty (B must be larger than A)")
    return a, b


class RunFrames(Struct):
    """The frames of one run: ``steps`` (sorted), their ``paths`` and ``times``."""

    folder: Path
    steps: list[int]
    paths: list[Path]
    times: list[float]


def load_run_frames(folder) -> RunFrames:
    """List the frames of the run in ``folder`` (by file name; times from series.pvd)."""
    folder = Path(folder)
    if not folder.is_dir():
        raise RenderError(f"{folder}: no such output folder")
    frames_dir = folder / FRAMES_DIR
    found = {}
    if frames_dir.is_dir():
        for p in frames_dir.iterdir():
            m = _FRAME_RE.match(p.name)
            if m:
                found[int(m.group(1))] = p
    if not found:
        raise RenderError(f"{folder}: no frames (no {FRAMES_DIR}/frame_*.vtu)")
    times = {}
    pvd = frames_dir / SERIES_NAME
    if pvd.is_file():
        try:
            for t, p in read_series(pvd):
                m = _FRAME_RE.match(p.name)
                if m:
                    times[int(m.group(1))] = t
        except FrameError:  # a damaged series only costs the times; frames carry TimeValue
            times = {}
    steps = sorted(found)
    return RunFrames(folder, steps, [found[s] for s in steps],
                     [times.get(s, math.nan) for s in steps])


def _read_frame(path: Path):
    try:
        return read_frame(path)
    except FrameError as exc:
        raise RenderError(str(exc)) from None


def _cells(mesh, kind: str) -> np.ndarray:
    blocks = [c.data for c in mesh.cells if c.type == kind]
    width = {"tetra": 4, "triangle": 3, "line": 2, "vertex": 1}[kind]
    if not blocks:
        return np.zeros((0, width), dtype=np.int64)
    return np.concatenate(blocks).astype(np.int64).reshape(-1, width)


def _poly_cells(polys: np.ndarray) -> np.ndarray:
    """VTK's flat cell layout [n, i0, ..., n, i0, ...]."""
    if len(polys) == 0:
        return np.zeros(0, dtype=np.int64)
    return np.hstack([np.full((len(polys), 1), polys.shape[1]), polys]).ravel()


def _plane_tile(pv, plane, center, extent):
    """A square tile of the plane through the point of it nearest the run's centre."""
    n = np.asarray(plane.normal, dtype=float)
    n = n / np.linalg.norm(n)
    o = np.asarray(plane.origin, dtype=float)
    c = center - np.dot(center - o, n) * n
    size = 3.0 * extent
    return pv.Plane(center=c, direction=n, i_size=size, j_size=size, i_resolution=1,
                    j_resolution=1)


def _line_segment(pv, plane, center, extent):
    """A 2D run's line: a segment of it through the point nearest the run's centre."""
    n = np.asarray(plane.normal, dtype=float)
    n = n / np.linalg.norm(n)
    c = center - np.dot(center - np.asarray(plane.origin, dtype=float), n) * n
    along = 1.5 * extent * np.array([-n[1], n[0], 0.0])
    return pv.Line(c - along, c + along)


def is_planar(mesh) -> bool:
    """A 2D run's frame: triangles and segments at z = 0, no tets."""
    points = np.asarray(mesh.points)
    return not len(_cells(mesh, "tetra")) and bool(np.all(points[:, 2] == 0.0))


def _camera(center, radius, azimuth, elevation, zoom, aspect, view_angle=30.0):
    """Camera position and up vector looking at ``center`` so that a sphere of
    ``radius`` fits the view (both directions), then zoomed."""
    az, el = math.radians(azimuth), math.radians(elevation)
    direction = np.array([math.sin(az) * math.cos(el), math.sin(el),
                          math.cos(az) * math.cos(el)])
    half = math.radians(view_angle) / 2  # vertical half angle
    half_h = math.atan(math.tan(half) * aspect)
    dist = radius / math.sin(min(half, half_h)) / zoom
    up = (0.0, 1.0, 0.0)
    if abs(elevation) > 89.0:  # looking straight down/up: y cannot be up on screen
        up = (-math.sin(az), 0.0, -math.cos(az))
    return center + dist * direction, up


def _quiet_vtk():
    """Silence VTK's warnings (the failed X connection before it falls back to EGL);
    returns a function restoring the previous level."""
    try:
        from vtkmodules.vtkCommonCore import vtkLogger
    except Exception:
        return lambda: None
    old = vtkLogger.GetCurrentVerbosityCutoff()
    vtkLogger.SetStderrVerbosity(vtkLogger.VERBOSITY_ERROR)
    return lambda: vtkLogger.SetStderrVerbosity(old)


def _save_png(path: Path, image: np.ndarray) -> None:
    from PIL import Image

    with atomic_path(path, fsync=False) as tmp:
        Image.fromarray(image).save(tmp, format="PNG")


def gif_writer_name() -> str:
    """Which library writes GIFs here: ``imageio`` when installed, else ``Pillow``."""
    try:
        import imageio  # noqa: F401
        return "imageio"
    except ImportError:
        return "Pillow"


def _write_gif(path: Path, images: list[np.ndarray], durations_s: list[float]) -> str:
    # GIF delays are in 1/100 s and viewers treat delays below 0.02 s as slow defaults
    ms = [max(20, int(round(d * 1000 / 10)) * 10) for d in durations_s]
    writer = gif_writer_name()
    with atomic_path(path, fsync=False) as tmp:
        if writer == "imageio":
            import imageio.v2 as imageio

            imageio.mimsave(tmp, images, format="GIF", duration=[m / 1000 for m in ms], loop=0)
        else:
            from PIL import Image

            frames = [Image.fromarray(im) for im in images]
            frames[0].save(tmp, format="GIF", save_all=True, append_images=frames[1:],
                           duration=ms, loop=0)
    return writer


def _check_mp4_encoder() -> None:
    try:
        import imageio  # noqa: F401
        import imageio_ffmpeg  # noqa: F401
    except ImportError as exc:
        raise RenderError("--mp4 needs an MP4 encoder: install the packages imageio and "
                          f"imageio-ffmpeg (pip install imageio imageio-ffmpeg); {exc}") from exc


def _write_mp4(path: Path, images: list[np.ndarray], fps: float) -> None:
    import imageio.v2 as imageio

    with atomic_path(path, fsync=False) as tmp:
        # the temporary name has no .mp4 ending, so name the format explicitly
        with imageio.get_writer(tmp, format="FFMPEG", mode="I", fps=fps,
                                codec="libx264", macro_block_size=2) as w:
            for im in images:
                w.append_data(im)


def _validate(opt: RenderOptions) -> tuple[int, int]:
    for name in ("azimuth", "elevation", "zoom"):
        if not math.isfinite(getattr(opt, name)):
            raise RenderError(f"--{name} must be a finite number, got {getattr(opt, name)}")
    if opt.every < 1:
        raise RenderError(f"--every must be at least 1, got {opt.every}")
    if opt.field not in ("none", "velocity"):
        raise RenderError(f"--field must be 'velocity' or 'none', got {opt.field!r}")
    if not opt.zoom > 0:
        raise RenderError(f"--zoom must be positive, got {opt.zoom}")
    if not -90.0 <= opt.elevation <= 90.0:
        raise RenderError(f"--elevation must be between -90 and 90 degrees, got {opt.elevation}")
    w, h = (int(v) for v in opt.size)
    if not (16 <= w <= 8192 and 16 <= h <= 8192):
        raise RenderError(f"--size must be between 16 and 8192 pixels each, got {w} {h}")
    return w, h


class FrameRenderer:
    """One offscreen plotter for the mesh of a run's ``first`` frame (meshio), with the
    camera fixed on the box [lo, hi]; ``draw(points, step, t, speeds)`` returns the RGB
    image of one frame. ``vmax`` is the top of the |velocity| colour scale (``--field
    velocity``)."""

    def __init__(self, first, planes, lo, hi, opt: RenderOptions, vmax: float | None = None):
        w, h = _validate(opt)
        n = len(first.points)
        planar = is_planar(first)
        if planar:  # a 2D run: seen from +z, x to the right, y up
            opt = RenderOptions(**{**{f: getattr(opt, f) for f in opt.__struct_fields__},
                                   "azimuth": 0.0, "elevation": 0.0})
        body = np.asarray(first.point_data.get("body_id", np.zeros(n)), dtype=np.int64).ravel()
        kin = np.asarray(first.point_data.get("kinematic", np.zeros(n)), dtype=np.int64).ravel()
        # a body is an obstacle when every vertex of it is prescribed
        nb = int(body.max()) + 1 if n else 0
        moving = np.bincount(body, weights=(kin == 0), minlength=nb) > 0
        obstacle_vertex = ~moving[body]

        from ..model.surface import boundary_triangles

        tris = np.concatenate([boundary_triangles(_cells(first, "tetra")),
                               _cells(first, "triangle")])
        lines, verts = _cells(first, "line"), _cells(first, "vertex")
        tri_obst = obstacle_vertex[tris].all(axis=1) if len(tris) else np.zeros(0, bool)
        center = (lo + hi) / 2
        extent = float(np.max(hi - lo)) or 1.0
        radius = 0.5 * float(np.linalg.norm(hi - lo)) or 0.5

        self._restore = _quiet_vtk()
        import pyvista as pv

        pv.OFF_SCREEN = True
        try:
            plotter = pv.Plotter(off_screen=True, window_size=(w, h))
        except Exception as exc:
            self._restore()
            raise RenderError(f"cannot open an offscreen render window: {exc}") from exc
        plotter.set_background("white")

        def poly(mask_tris, with_lines):
            p = pv.PolyData(np.asarray(first.points, dtype=float),
                            faces=_poly_cells(tris[mask_tris]) if mask_tris.any() else None)
            if with_lines and len(lines):
                p.lines = _poly_cells(lines)
            if with_lines and len(verts):
                p.verts = _poly_cells(verts)
            return p

        self.body_mesh = poly(~tri_obst, True)
        self.obst_mesh = poly(tri_obst, False) if tri_obst.any() else None
        self.colour_by_speed = vmax is not None
        if not self.colour_by_speed:
            rgb = PALETTE[body % len(PALETTE)].copy()
            rgb[obstacle_vertex] = OBSTACLE_RGB
            self.body_mesh.point_data["rgb"] = rgb
            plotter.add_mesh(self.body_mesh, scalars="rgb", rgb=True, smooth_shading=False,
                             line_width=3, point_size=8, render_points_as_spheres=True,
                             show_edges=planar, edge_color="white")
        else:
            self.body_mesh.point_data["|v| m/s"] = np.zeros(n)
            plotter.add_mesh(self.body_mesh, scalars="|v| m/s", cmap="viridis",
                             clim=(0.0, vmax), line_width=3, point_size=8,
                             render_points_as_spheres=True,
                             scalar_bar_args={"color": "black", "vertical": True,
                                              "title": "|v| m/s", "position_x": 0.88,
                                              "position_y": 0.2, "width": 0.06,
                                              "height": 0.6, "label_font_size": 10,
                                              "title_font_size": 12})
        if self.obst_mesh is not None:
            plotter.add_mesh(self.obst_mesh, color=np.array(OBSTACLE_RGB) / 255)
        for pl in planes:
            if planar:  # a moving line is not drawn: it is elsewhere in every frame
                if not np.any(np.asarray(pl.velocity, dtype=float) != 0.0):
                    plotter.add_mesh(_line_segment(pv, pl, center, extent),
                                     color=np.array(PLANE_RGB) / 255 * 0.6, line_width=4)
                continue
            plotter.add_mesh(_plane_tile(pv, pl, center, extent),
                             color=np.array(PLANE_RGB) / 255, opacity=0.6)

        pos, up = _camera(center, radius, opt.azimuth, opt.elevation, opt.zoom, w / h)
        plotter.camera.position = tuple(pos)
        plotter.camera.focal_point = tuple(center)
        plotter.camera.up = up
        plotter.camera.view_angle = 30.0
        self.plotter = plotter

    def draw(self, points, step: int, t: float, speeds=None) -> np.ndarray:
        pts = np.asarray(points, dtype=float)
        self.body_mesh.points = pts
        if self.obst_mesh is not None:
            self.obst_mesh.points = pts
        if self.colour_by_speed and speeds is not None:
            self.body_mesh.point_data["|v| m/s"] = speeds
        tt = f"t = {t:.3f} s" if not math.isnan(t) else "t = ?"
        # same name: replaces the previous frame's stamp
        self.plotter.add_text(f"{tt}   step {step}", position="upper_left", font_size=12,
                              color="black", name="time_stamp")
        self.plotter.renderer.ResetCameraClippingRange()
        self.plotter.render()
        return np.asarray(self.plotter.screenshot(return_img=True))[:, :, :3].copy()

    def close(self) -> None:
        if self.plotter is not None:
            self.plotter.close()
            self.plotter = None
            self._restore()


def render_run(folder, options: RenderOptions | None = None, say=print,
               planes=()) -> dict:
    """Render the run in ``folder`` with the scene's ``planes`` (PlaneSpecs, drawn as
    ground or half spaces); returns ``{"pngs": [...], "gif": path|None, "mp4":
    path|None, "gif_writer": name|None}``."""
    opt = options or RenderOptions()
    _validate(opt)
    if opt.mp4:
        _check_mp4_encoder()  # before spending time on rendering

    run = load_run_frames(folder)
    a, b = opt.frames
    pick = [i for i, s in enumerate(run.steps)
            if (a is None or s >= a) and (b is None or s < b)]
    pick = pick[:: opt.every]
    if not pick:
        raise RenderError(f"{run.folder}: no frames in the selected range "
                          f"(the run has steps {run.steps[0]}..{run.steps[-1]})")
    out_dir = Path(opt.output) if opt.output is not None else run.folder / "render"

    # Read every selected frame first: the camera and the colour scale cover the whole run.
    meshes = [_read_frame(run.paths[i]) for i in pick]
    first = meshes[0]
    n = len(first.points)
    for i, m in zip(pick, meshes):
        if len(m.points) != n:
            raise RenderError(f"{run.paths[i]}: {len(m.points)} vertices, the first frame "
                              f"has {n}")
    try:  # only now that every frame has been read: a damaged run changes nothing
        out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise RenderError(f"cannot create {out_dir}: {exc.strerror or exc}") from None
    allpts = np.concatenate([m.points for m in meshes])
    finite = np.isfinite(allpts).all(axis=1)
    if not finite.any():
        raise RenderError(f"{run.folder}: the frames hold no finite positions")
    lo, hi = allpts[finite].min(axis=0), allpts[finite].max(axis=0)

    speeds, vmax = [None] * len(meshes), None
    if opt.field == "velocity":
        speeds = [np.linalg.norm(np.asarray(m.point_data.get("velocity", np.zeros((n, 3)))),
                                 axis=1) for m in meshes]
        vmax = max(float(np.nanmax(s)) if s.size else 0.0 for s in speeds) or 1.0

    times = []
    for i, m in zip(pick, meshes):
        t = run.times[i]
        if math.isnan(t):
            tv = m.field_data.get("TimeValue")
            t = float(np.ravel(tv)[0]) if tv is not None and np.size(tv) else math.nan
        times.append(t)

    renderer = FrameRenderer(first, planes, lo, hi, opt, vmax)
    pngs, images = [], []
    try:
        for k, (i, m) in enumerate(zip(pick, meshes)):
            img = renderer.draw(m.points, run.steps[i], times[k], speeds[k])
            png = out_dir / (run.paths[i].stem + ".png")
            _save_png(png, img)
            pngs.append(png)
            if opt.gif or opt.mp4:
                images.append(img)
    finally:
        renderer.close()

    result = {"pngs": pngs, "gif": None, "mp4": None, "gif_writer": None}
    dts = np.diff(times) if len(times) > 1 else np.array([0.04])
    dts = [float(d) if np.isfinite(d) and d > 0 else 0.04 for d in dts]
    if opt.gif:
        gif = out_dir / "animation.gif"
        result["gif_writer"] = _write_gif(gif, images, dts + [dts[-1]])
        result["gif"] = gif
    if opt.mp4:
        mp4 = out_dir / "animation.mp4"
        _write_mp4(mp4, images, fps=min(60.0, max(1.0, 1.0 / float(np.median(dts)))))
        result["mp4"] = mp4
    return result


class LiveRenderer:
    """``ipcsim run --render``: a PNG per frame as the run writes it, into OUT/render.

    The whole run is not known yet, so the camera frames the initial frame together with
    the origins of the scene's planes (a falling body stays in view down to the ground)."""

    def __init__(self, folder, options: RenderOptions | None = None, planes=()):
        self.folder = Path(folder)
        self.options = options or RenderOptions()
        self.planes = list(planes)
        self.out_dir = self.folder / "render"
        self._renderer = None

    def _start(self):
        first = _read_frame(self.folder / FRAMES_DIR / frame_file_name(0))
        planes = self.planes
        pts = np.concatenate([first.points] + [np.asarray([p.origin], float) for p in planes])
        lo, hi = pts.min(axis=0), pts.max(axis=0)
        self.out_dir.mkdir(parents=True, exist_ok=True)
        self._renderer = FrameRenderer(first, planes, lo, hi, self.options)

    def render(self, step: int, t: float, points) -> Path:
        if self._renderer is None:
            self._start()
        png = self.out_dir / Path(frame_file_name(step)).with_suffix(".png")
        _save_png(png, self._renderer.draw(points, step, t))
        return png

    def close(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
