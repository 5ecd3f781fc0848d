"""`ipcsim render`: offscreen pictures of a real two-body run."""

from __future__ import annotations

import colorsys

import numpy as np
import pytest
from generated import write_box_msh
from PIL import Image

from ipcsim.cli import main
from ipcsim.io.render import PALETTE, RenderError, parse_frame_range


@pytest.fixture(scope="module")
def two_body_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("render")
    write_box_msh(tmp / "cube.msh")
    scene = tmp / "two.txt"
    # body 0 on the left (x < 0), body 1 on the right
    scene.write_text("shapes input 2\ncube.msh -0.3 0.05 0  0 0 0  1 1 1\n"
                     "cube.msh 0.3 0.05 0  0 0 0  1 1 1\nselfCollisionOff\nground 0 0\n"
                     "time 0.05 0.01\n")
    out = tmp / "out"
    assert main(["run", str(scene), "-o", str(out), "--steps", "3", "-q"]) == 0
    return out


def _hue_mask(img: np.ndarray, rgb) -> np.ndarray:
    """Pixels whose hue is that of ``rgb`` (shading changes brightness, not hue)."""
    h0 = colorsys.rgb_to_hsv(*(np.array(rgb) / 255))[0]
    import matplotlib.colors as mc

    hsv = mc.rgb_to_hsv(img[:, :, :3] / 255.0)
    dh = np.abs(hsv[:, :, 0] - h0)
    dh = np.minimum(dh, 1 - dh)
    return (dh < 0.03) & (hsv[:, :, 1] > 0.4) & (hsv[:, :, 2] > 0.15)


def test_render_places_bodies_where_they_are(two_body_run, tmp_path):
    dest = tmp_path / "pics"
    assert main(["render", str(two_body_run), "--azimuth", "0", "--elevation", "0",
                 "--size", "320", "240", "--gif", "-q", "-o", str(dest)]) == 0
    pngs = sorted(dest.glob("frame_*.png"))
    assert [p.name for p in pngs] == [f"frame_00000{i}.png" for i in range(4)]
    img = np.asarray(Image.open(pngs[-1]).convert("RGB"))
    assert img.shape == (240, 320, 3)
    assert img.std() > 10  # not a blank picture
    left, right = _hue_mask(img, PALETTE[0]), _hue_mask(img, PALETTE[1])
    assert left.sum() > 200 and right.sum() > 200
    # front camera (x to the right): body 0 left of the centre, body 1 right of it
    assert np.nonzero(left)[1].mean() < 160 - 40
    assert np.nonzero(right)[1].mean() > 160 + 40
    gif = Image.open(dest / "animation.gif")
    assert gif.n_frames == 4


def test_render_options_and_errors(two_body_run, tmp_path, capsys):
    dest = tmp_path / "v"
    assert main(["render", str(two_body_run), "--frames", "1:3", "--field", "velocity",
                 "--size", "64", "48", "-q", "-o", str(dest)]) == 0
    assert sorted(p.name for p in dest.glob("*.png")) == ["frame_000001.png",
                                                         "frame_000002.png"]
    assert main(["render", str(tmp_path / "nothing"), "-q"]) == 2
    assert "no such output folder" in capsys.readouterr().err
    assert main(["render", str(two_body_run), "--frames", "7:9", "-q"]) == 2
    assert "no frames in the selected range" in capsys.readouterr().err
    with pytest.raises(RenderError, match="A:B"):
        parse_frame_range("3-5")
    assert parse_frame_range("10:") == (10, None)


def test_mp4_without_encoder_is_a_clear_error(two_body_run, capsys):
    try:
        import imageio  # noqa: F401
        import imageio_ffmpeg  # noqa: F401
        pytest.skip("an MP4 encoder is installed")
    except ImportError:
        pass
    assert main(["render", str(two_body_run), "--mp4", "-q"]) == 2
    assert "imageio-ffmpeg" in capsys.readouterr().err


def test_run_render_draws_each_frame_as_it_is_written(two_body_run, tmp_path):
    scene = two_body_run.parent / "two.txt"
    out = tmp_path / "live"
    assert main(["run", str(scene), "-o", str(out), "--steps", "2", "-q", "--render"]) == 0
    pngs = sorted((out / "render").glob("frame_*.png"))
    assert [p.name for p in pngs] == [f"frame_00000{i}.png" for i in range(3)]
    img = np.asarray(Image.open(pngs[-1]).convert("RGB"))
    left, right = _hue_mask(img, PALETTE[0]), _hue_mask(img, PALETTE[1])
    assert left.sum() > 200 and right.sum() > 200
    assert np.nonzero(left)[1].mean() < np.nonzero(right)[1].mean()  # default camera, azimuth 30
