"""Helpers shared by the test modules, in one place: the command line in-process, small
sweeps and sweep files (interrupting one, comparing two, damaging one), and the pixels of a
written picture.

Picture checks look at content, not file size: a PNG read back with matplotlib's reader, its
size in pixels, the colours it holds and in what shares. Colours are compared channel by
channel within :data:`NEAR` (PNG keeps 8 bits a channel; edges are antialiased), so a share
counts the pixels of one flat colour, not the blends at its borders.
"""

from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
CONFIGS = ROOT / "configs"

NEAR = 6 / 255  # a pixel within this of a colour on every channel has that colour


# --- the command line ---------------------------------------------------------------------


def ctrl_c_reaches_it():
    """``preexec_fn`` for a child that a test stops with SIGINT: its Ctrl-C back to the default.
    A suite started as a background job (``make test &``) runs with SIGINT ignored, the child
    inherits that, and the server never heard the test's Ctrl-C (two view tests timed out)."""
    import signal

    signal.signal(signal.SIGINT, signal.SIG_DFL)


def invoke(*args):
    """Invoke ``dice-sweep`` in-process; ``result.output`` holds stdout and stderr together."""
    from click.testing import CliRunner

    from dice_sweep.cli import main

    return CliRunner().invoke(main, [str(arg) for arg in args])


def run_cli(*args):
    """Invoke ``dice-sweep`` in-process with stderr apart from stdout (``result.stderr``;
    click 8.1 needs mix_stderr=False, click >= 8.2 always keeps them apart)."""
    from click.testing import CliRunner

    from dice_sweep.cli import main

    try:
        runner = CliRunner(mix_stderr=False)
    except TypeError:
        runner = CliRunner()
    return runner.invoke(main, [str(arg) for arg in args])


# --- sweeps -------------------------------------------------------------------------------


def small_sweep(cfg, path, **options):
    """Run a sweep of ``cfg`` into ``path`` quietly, in this process unless ``workers`` says
    otherwise; returns run_sweep's summary."""
    from dice_sweep.sweep import run_sweep

    return run_sweep(cfg, path, **{"workers": 1, "progress": False, **options})


def stop_after(n_tiles):
    """An ``on_tile`` hook that presses Ctrl-C once ``n_tiles`` tiles are written."""
    written = []

    def on_tile(index, rolls):
        written.append(index)
        if len(written) == n_tiles:
            raise KeyboardInterrupt

    return on_tile


def assert_same_maps(data, reference):
    """Every map of two sweeps equal bitwise (NaNs included)."""
    for name in ("outcome", "status", "impacts", "t_decided"):
        assert getattr(data, name).tobytes() == getattr(reference, name).tobytes(), name
    assert data.counts.keys() == reference.counts.keys()
    for name, counts in data.counts.items():
        assert counts.tobytes() == reference.counts[name].tobytes(), name
    assert data.x.values.tobytes() == reference.x.values.tobytes()
    assert data.y.values.tobytes() == reference.y.values.tobytes()


def corrupt_first_chunk(path, dataset="outcome"):
    """Overwrite 20 bytes inside the first stored chunk of ``dataset`` of an HDF5 sweep file."""
    import h5py

    with h5py.File(path, "r") as h5:
        offset = h5[dataset].id.get_chunk_info(0).byte_offset
    with open(path, "r+b") as file:
        file.seek(offset + 10)
        file.write(b"\xff" * 20)


def replace_dataset(h5, name, data):
    """Put ``data`` in place of dataset ``name`` of an open h5py file, its attributes kept (a
    forged map: another shape or dtype; scripts/bad_inputs.py forges with it too)."""
    attrs = {key: value for key, value in h5[name].attrs.items() if key not in ("DIMENSION_LIST", "_FillValue")}
    for dim in h5[name].dims:
        for scale in list(dim.values()):
            dim.detach_scale(scale)
    del h5[name]
    h5.create_dataset(name, data=data).attrs.update(attrs)


def set_first(name, value):
    """A change (for an open h5py file) that puts ``value`` in the first cell of dataset ``name``."""
    def change(h5):
        values = h5[name][...]
        values.flat[0] = value
        h5[name][...] = values
    return change


# --- pictures -----------------------------------------------------------------------------


def read_png(path):
    """The PNG at ``path`` as an RGBA float array (rows top down, values in [0, 1])."""
    from matplotlib.image import imread

    image = imread(path)
    assert image.ndim == 3 and image.shape[2] in (3, 4), image.shape
    if image.shape[2] == 3:
        image = np.concatenate([image, np.ones(image.shape[:2] + (1,), image.dtype)], axis=2)
    return image


def png_size(path):
    """(width, height) in pixels of the PNG at ``path``."""
    height, width = read_png(path).shape[:2]
    return width, height


def figure_pixels(figsize, dpi):
    """(width, height) in pixels of a figure of ``figsize`` inches saved at ``dpi``."""
    return tuple(int(inches * dpi) for inches in figsize)


def near(image, colour, tol=NEAR):
    """Mask of the pixels of ``image`` within ``tol`` of ``colour`` (RGB or RGBA; RGB compared)."""
    return np.all(np.abs(image[..., :3] - np.asarray(colour, float)[:3]) <= tol, axis=-1)


def share(image, colour, tol=NEAR):
    """Share of the pixels of ``image`` that have ``colour``."""
    return float(near(image, colour, tol).mean())


def _longest_run(flags):
    """(start, stop) of the longest run of True in a 1-D boolean array ((0, 0) if none)."""
    best, start = (0, 0), None
    for i, flag in enumerate(np.append(flags, False)):
        if flag and start is None:
            start = i
        elif not flag and start is not None:
            if i - start > best[1] - best[0]:
                best = (start, i)
            start = None
    return best


def map_region(image, colours=None, tol=NEAR, inset=3):
    """The part of ``image`` where a map is drawn: the longest run of columns in which most
    pixels have one of ``colours`` (default: any colour but white), then within those columns
    the longest such run of rows, less ``inset`` pixels on each side (the axes' frame,
    antialiased edges). A colour bar beside the map is a shorter run of columns: left out."""
    if colours is None:
        mask = ~near(image, (1.0, 1.0, 1.0), tol)
    else:
        mask = np.zeros(image.shape[:2], bool)
        for colour in colours:
            mask |= near(image, colour, tol)
    c0, c1 = _longest_run(mask.mean(axis=0) > 0.5)
    r0, r1 = _longest_run(mask[:, c0:c1].mean(axis=1) > 0.5)
    assert c1 - c0 > 2 * inset and r1 - r0 > 2 * inset, "no map in the picture"
    return image[r0 + inset : r1 - inset, c0 + inset : c1 - inset]


def pixels_around(fig, x, y, png_path, reach=0):
    """RGBA pixels of the saved PNG within ``reach`` pixels of data point (x, y) of the
    figure's first axes (``fig`` the Figure that was saved, for its transforms)."""
    fig.canvas.draw()
    display_x, display_y = fig.axes[0].transData.transform((x, y))
    image = read_png(png_path)
    row, column = image.shape[0] - 1 - int(display_y), int(display_x)
    return image[row - reach : row + reach + 1, column - reach : column + reach + 1].reshape(-1, 4)


def pixel_at(fig, x, y, png_path):
    """RGBA of the saved PNG at data point (x, y) of the figure's first axes."""
    return pixels_around(fig, x, y, png_path)[0]
