from __future__ import annotations

import time as _time

import meshio
import numpy as np
import pytest

from ipcsim.io.vtk import FrameWriter, frame_file_name, frame_interval, read_series

pv = pytest.importorskip("pyvista")

TIMES = [0.0, 0.01, 0.02, 0.035]


def small_scene():
    """Two tets sharing a face (body 0), an obstacle quad of two triangles (body 1),
    a segment (body 2) and a point (body 3)."""
    tet_x = np.array(
        [[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1]], dtype=float
    )
    obstacle_x = np.array([[-2, -1, -2], [2, -1, -2], [2, -1, 2], [-2, -1, 2]], dtype=float)
    seg_x = np.array([[0, 3, 0], [1, 3, 0]], dtype=float)
    pt_x = np.array([[0, 4, 0]], dtype=float)
    x = np.vstack([tet_x, obstacle_x, seg_x, pt_x])
    tets = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    triangles = np.array([[5, 6, 7], [5, 7, 8]])
    segments = np.array([[9, 10]])
    points = np.array([11])
    body_id = np.array([0] * 5 + [1] * 4 + [2] * 2 + [3])
    return x, tets, triangles, segments, points, body_id


@pytest.fixture(params=[1, None], ids=["zlib", "raw"])
def written(tmp_path, request):
    """A run folder with four frames; returns what was written, frame by frame."""
    x0, tets, triangles, segments, points, body_id = small_scene()
    writer = FrameWriter(
        tmp_path, tets, triangles, body_id, segments=segments, points=points,
        compression_level=request.param,
    )
    rng = np.random.default_rng(7)
    kinematic = body_id == 1
    frames = []
    for i, t in enumerate(TIMES):
        x = x0 + rng.normal(scale=0.1, size=x0.shape) * ~kinematic[:, None]
        v = rng.normal(size=x0.shape)
        d = rng.random(len(x0))
        path = writer.write(i, t, x, v, kinematic=kinematic, contact_distance=d)
        frames.append((path, t, x, v, d))
    return writer, frames


def test_frames_read_back_with_meshio(written):
    writer, frames = written
    _, tets, triangles, segments, points, body_id = small_scene()
    for i, (path, t, x, v, d) in enumerate(frames):
        assert path == writer.frames_dir / frame_file_name(i)
        mesh = meshio.read(path)
        np.testing.assert_array_equal(mesh.points, x)
        cells = mesh.cells_dict
        np.testing.assert_array_equal(cells["tetra"], tets)
        np.testing.assert_array_equal(cells["triangle"], triangles)
        np.testing.assert_array_equal(cells["line"], segments)
        np.testing.assert_array_equal(cells["vertex"].ravel(), points)
        np.testing.assert_array_equal(mesh.point_data["body_id"], body_id)
        np.testing.assert_array_equal(mesh.point_data["velocity"], v)
        np.testing.assert_array_equal(mesh.point_data["contact_distance"], d)
        np.testing.assert_array_equal(mesh.point_data["kinematic"], (body_id == 1).astype(np.uint8))
        assert mesh.field_data["TimeValue"][0] == t


def test_series_plays_in_pyvista(written):
    writer, frames = written
    reader = pv.get_reader(str(writer.series_path))
    assert reader.number_time_points == len(TIMES)
    assert reader.time_values == pytest.approx(TIMES, abs=0)
    reader.set_active_time_value(TIMES[2])
    grid = reader.read()[0]
    _, t, x, v, d = frames[2]
    np.testing.assert_array_equal(grid.points, x)
    np.testing.assert_array_equal(grid.point_data["velocity"], v)
    np.testing.assert_array_equal(grid.point_data["contact_distance"], d)
    # VTK cell types: tetra 10, triangle 5, line 3, vertex 1
    np.testing.assert_array_equal(grid.celltypes, [10, 10, 5, 5, 3, 1])
    assert grid.field_data["TimeValue"][0] == t


def test_series_lists_every_frame_with_exact_time(written):
    writer, frames = written
    series = read_series(writer.series_path)
    assert [t for t, _ in series] == TIMES
    assert [p for _, p in series] == [f[0] for f in frames]
    assert [(i, t) for i, t, _ in writer.frames] == list(enumerate(TIMES))
    names = sorted(p.name for p in writer.frames_dir.iterdir())
    assert names == [frame_file_name(i) for i in range(len(TIMES))] + ["series.pvd"]


def test_rewriting_a_frame_replaces_its_series_entry(tmp_path):
    x, tets, triangles, _, _, body_id = small_scene()
    writer = FrameWriter(tmp_path, tets, triangles, body_id)
    v = np.zeros_like(x)
    writer.write(0, 0.0, x, v)
    writer.write(1, 0.5, x, v)
    writer.write(1, 0.25, x + 1, v)
    assert [t for t, _ in read_series(writer.series_path)] == [0.0, 0.25]
    np.testing.assert_array_equal(meshio.read(writer.frames_dir / frame_file_name(1)).points, x + 1)



def test_a_series_interval_lets_the_series_lag_until_flush_or_sync(tmp_path):
    """With ``series_interval`` the series is rewritten with a frame only when that many
    seconds have passed; ``flush`` and ``sync`` bring it up to date."""
    x, tets, triangles, _, _, body_id = small_scene()
    writer = FrameWriter(tmp_path, tets, triangles, body_id)
    writer.series_interval = 3600.0
    v = np.zeros_like(x)
    writer.write(0, 0.0, x, v)  # the first frame writes the series
    writer.write(1, 0.5, x, v)
    writer.write(2, 1.0, x, v)
    assert [t for t, _ in read_series(writer.series_path)] == [0.0]
    writer.flush()
    assert [t for t, _ in read_series(writer.series_path)] == [0.0, 0.5, 1.0]
    writer.write(3, 1.5, x, v)
    writer.sync()
    assert [t for t, _ in read_series(writer.series_path)] == [0.0, 0.5, 1.0, 1.5]
    assert [i for i, _, _ in writer.frames] == [0, 1, 2, 3]

def test_without_cells_every_vertex_becomes_a_vertex_cell(tmp_path):
    writer = FrameWriter(tmp_path, np.zeros((0, 4), dtype=int), [], [0, 0, 1])
    path = writer.write(0, 0.0, np.eye(3), np.zeros((3, 3)))
    np.testing.assert_array_equal(meshio.read(path).cells_dict["vertex"].ravel(), [0, 1, 2])
    np.testing.assert_array_equal(pv.read(path).celltypes, [1, 1, 1])


def test_writer_rejects_bad_input(tmp_path):
    x, tets, triangles, _, _, body_id = small_scene()
    with pytest.raises(ValueError, match="outside"):
        FrameWriter(tmp_path, tets, [[0, 1, len(x)]], body_id)
    with pytest.raises(ValueError, match="shape"):
        FrameWriter(tmp_path, tets[:, :3], None, body_id)
    with pytest.raises(TypeError):
        FrameWriter(tmp_path, tets.astype(float), None, body_id)
    with pytest.raises(ValueError, match="vertex"):
        FrameWriter(tmp_path, None, None, np.zeros(0, dtype=int))
    writer = FrameWriter(tmp_path, tets, triangles, body_id)
    v = np.zeros_like(x)
    with pytest.raises(ValueError, match="positions"):
        writer.write(0, 0.0, x[:-1], v)
    with pytest.raises(ValueError, match="contact_distance"):
        writer.write(0, 0.0, x, v, contact_distance=np.zeros(3))
    with pytest.raises(ValueError, match="body_id"):
        writer.write(0, 0.0, x, v, body_id=np.zeros(len(x), int))
    assert not any(writer.frames_dir.iterdir())


def test_large_frame_writes_fast(tmp_path):
    # 50,000 vertices on a grid, ~280,000 tets: the size the writer is meant for
    k = 37
    i, j, l = np.meshgrid(np.arange(k), np.arange(k), np.arange(k), indexing="ij")
    x = np.stack([i, j, l], -1).reshape(-1, 3) * 0.01
    a, b, c = (g[:-1, :-1, :-1].ravel() for g in (i, j, l))
    corner = [
        ((a + dx) * k + b + dy) * k + c + dz for dx in (0, 1) for dy in (0, 1) for dz in (0, 1)
    ]
    tets = np.concatenate(
        [np.stack([corner[p] for p in t], 1) for t in
         [(0, 1, 3, 7), (0, 1, 5, 7), (0, 2, 3, 7), (0, 2, 6, 7), (0, 4, 5, 7), (0, 4, 6, 7)]]
    )
    writer = FrameWriter(tmp_path, tets, None, np.zeros(len(x), dtype=np.int64))
    v = np.cos(x)
    start = _time.perf_counter()
    path = writer.write(0, 0.0, x, v, kinematic=np.zeros(len(x), bool))
    elapsed = _time.perf_counter() - start
    assert elapsed < 1.0, f"a 50k-vertex frame took {elapsed:.3f} s"
    np.testing.assert_array_equal(meshio.read(path).points, x)


@pytest.mark.parametrize(
    ("dt", "expected"), [(0.01, 1), (0.001, 10), (0.003, 3), (0.025, 1), (1e-4, 100)]
)
def test_frame_interval(dt, expected):
    assert frame_interval(dt) == expected


def test_frame_interval_rejects_nonpositive_dt():
    with pytest.raises(ValueError):
        frame_interval(0.0)


def test_a_runs_frames_are_compressed_from_a_thousand_vertices(repo_root, tmp_path):
    """Small frames go uncompressed (zlib's set-up costs more than the bytes it saves),
    larger ones compressed; both read back the same way."""
    import ipcsim
    from ipcsim.io.vtk import COMPRESS_FROM, frame_compression

    assert frame_compression(COMPRESS_FROM - 1) is None and frame_compression(COMPRESS_FROM) == 1
    spec = ipcsim.load_scene(repo_root / "input" / "cube_drop.toml", {"time.duration": 0.05})
    result = ipcsim.run(spec, tmp_path / "run")
    frame = sorted((tmp_path / "run" / "frames").glob("frame_*.vtu"))[-1]  # the last step's
    assert ipcsim.build_model(spec).n_vertices < COMPRESS_FROM
    assert "compressor" not in frame.read_text()[:400]
    np.testing.assert_array_equal(meshio.read(frame).points, result.state.x)
