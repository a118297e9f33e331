"""Fuzzing the measured-run loader: malformed files give MeasuredDataError, never a crash.

Two families:

* structural corruptions written with h5py into an unsealed copy (user block
  zeroed, as a file written by another tool would be): missing items, wrong
  shapes and dtypes, NaN / inf, bad attributes, bad units, changed values;
* byte-level corruptions of a sealed file (truncation, flipped bytes, garbage).

Every case must raise :class:`MeasuredDataError` naming the file; byte flips
may also leave the run unchanged (padding), never silently different.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable
from pathlib import Path

import h5py
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from susp_bo.data.measured import MeasuredDataError, MeasuredRun, load_run, save_run
from susp_bo.rig.track import SpeedProfile, TrackGeometry

NUMERIC = (
    "geometry/vertical_m",
    "geometry/alignment_m",
    "geometry/cross_level_rad",
    "geometry/gauge_m",
    "speed/time_s",
    "speed/speed_m_s",
    "accelerations/data",
)
STRINGS = ("accelerations/channels", "accelerations/units")
GROUPS = ("geometry", "speed", "accelerations")
UNITS = {
    "geometry/vertical_m": "m",
    "geometry/alignment_m": "m",
    "geometry/cross_level_rad": "rad",
    "geometry/gauge_m": "m",
    "speed/time_s": "s",
    "speed/speed_m_s": "m/s",
}
FUZZ = settings(max_examples=80, deadline=None, suppress_health_check=[HealthCheck.too_slow])


def _base_run() -> MeasuredRun:
    rng = np.random.default_rng(3)
    return MeasuredRun(
        geometry=TrackGeometry.synthetic("high", length_m=60.0, seed=3),
        speed=SpeedProfile(np.array([0.0, 1.0, 2.0]), np.array([20.0, 22.0, 21.0])),
        channels=("carbody_z", "bogie_y", "axle_z"),
        accelerations_m_s2=rng.normal(size=(3, 200)),
        sample_rate_hz=100.0,
        metadata={"rig": "hst_trailer", "seed": 3},
    )


BASE_RUN = _base_run()
with tempfile.TemporaryDirectory() as _folder:
    BASE_BYTES = save_run(BASE_RUN, Path(_folder) / "base.h5").read_bytes()


def _replace(file: h5py.File, path: str, data: object, **kwargs: object) -> None:
    del file[path]
    file.create_dataset(path, data=data, **kwargs)


def _mutations(draw: st.DataObject) -> tuple[str, Callable[[h5py.File], None]]:
    """A named corruption, drawn by hypothesis, that applies itself to an open file."""
    kind = draw.draw(
        st.sampled_from(
            [
                "delete",
                "shape",
                "dtype",
                "nonfinite",
                "value",
                "attribute",
                "drop_attribute",
                "units",
                "strings",
                "speed",
            ]
        ),
        label="kind",
    )
    if kind == "delete":
        path = draw.draw(st.sampled_from(NUMERIC + STRINGS + GROUPS))
        return f"delete {path}", lambda f: f.__delitem__(path)
    if kind == "shape":
        path = draw.draw(st.sampled_from(NUMERIC))
        shape = draw.draw(st.sampled_from([(), (0,), (1,), (3, 4, 2), (7, 3)]))
        if path == "accelerations/data":
            shape = draw.draw(st.sampled_from([(), (200,), (4, 200), (3, 1), (0, 200)]))
        return f"shape {path} {shape}", lambda f: _replace(f, path, np.ones(shape))
    if kind == "dtype":
        path = draw.draw(st.sampled_from(NUMERIC))
        length = len(BASE_RUN.geometry.vertical_m)
        data = draw.draw(
            st.sampled_from(
                [
                    np.array(["1.0"] * 3, dtype=object),
                    np.ones(length, dtype=bool),
                    np.ones(length, dtype=np.complex128),
                    np.zeros(3, dtype=[("a", "f8"), ("b", "i4")]),
                ]
            )
        )
        kwargs = {"dtype": h5py.string_dtype()} if data.dtype == object else {}
        return f"dtype {path} {data.dtype}", lambda f: _replace(f, path, data, **kwargs)
    if kind == "nonfinite":
        path = draw.draw(st.sampled_from(NUMERIC))
        value = draw.draw(st.sampled_from([np.nan, np.inf, -np.inf]))
        fraction = draw.draw(st.floats(0.0, 0.999))

        def nonfinite(f: h5py.File) -> None:
            data = np.array(f[path][()])
            flat = data.reshape(-1)
            flat[int(fraction * flat.size)] = value
            f[path][...] = data

        return f"{value} in {path}", nonfinite
    if kind == "value":  # a plausible, finite change: only the content checksum sees it
        path = draw.draw(st.sampled_from(NUMERIC))
        fraction = draw.draw(st.floats(0.0, 0.999))

        def perturb(f: h5py.File) -> None:
            data = np.array(f[path][()])
            flat = data.reshape(-1)
            flat[int(fraction * flat.size)] *= 1.0 + 1e-9
            flat[int(fraction * flat.size)] += 1e-12
            f[path][...] = data

        return f"perturb {path}", perturb
    if kind == "attribute":
        target, name = draw.draw(
            st.sampled_from(
                [
                    ("accelerations", "sample_rate_hz"),
                    ("accelerations", "time_offset_s"),
                    ("geometry", "spacing_m"),
                    ("/", "format"),
                    ("/", "format_version"),
                    ("/", "metadata_json"),
                    ("/", "content_sha256"),
                ]
            )
        )
        value = draw.draw(
            st.sampled_from(
                [-100.0, 0.0, np.nan, np.inf, "100", np.array([1.0, 2.0]), True, -1, 2, "[1, 2]"]
            )
        )
        plain_number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if name == "time_offset_s" and plain_number and value in (0.0, 2):
            value = -0.5  # 0 and 2 are valid offsets
        if name == "metadata_json" and isinstance(value, str):
            value = draw.draw(st.sampled_from(["[1, 2]", "{not json", "5"]))
        if name == "format_version" and plain_number and value in (1, 2, 3):
            value = 4  # 1, 2 and 3 are readable versions (3 may hold /geometry)
        return f"attribute {target}:{name} = {value!r}", lambda f: f[target].attrs.__setitem__(
            name, value
        )
    if kind == "drop_attribute":
        target, name = draw.draw(
            st.sampled_from(
                [
                    ("accelerations", "sample_rate_hz"),
                    ("geometry", "spacing_m"),
                    ("/", "format"),
                    ("/", "format_version"),
                    ("/", "metadata_json"),
                    *((path, "units") for path in UNITS),
                ]
            )
        )
        return f"drop {target}:{name}", lambda f: f[target].attrs.__delitem__(name)
    if kind == "units":
        path = draw.draw(st.sampled_from(list(UNITS)))
        unit = draw.draw(st.sampled_from(["mm", "ft", "", "m/s^2", "deg", "km/h"]))
        if unit == UNITS[path]:
            unit = "furlong"
        return f"units {path} = {unit!r}", lambda f: f[path].attrs.__setitem__("units", unit)
    if kind == "strings":
        path = draw.draw(st.sampled_from(STRINGS))
        values = draw.draw(
            st.sampled_from(
                [
                    ["a", "b"],  # wrong count
                    ["a", "a", "b"],  # duplicates (channels) / unknown-but-3 units
                    ["", "b", "c"],
                    ["a", "b", "c", "d"],
                ]
            )
        )
        if path == "accelerations/units" and values == ["a", "a", "b"]:
            values = ["m/s^2", "m/s^2"]
        if path == "accelerations/units" and values == ["", "b", "c"]:
            values = ["m/s^2", "g", "m/s^2"]  # valid units but not what was saved
        numeric = draw.draw(st.booleans())
        if numeric:
            return f"numbers in {path}", lambda f: _replace(f, path, np.arange(3.0))
        data = np.array(values, dtype=object)
        return f"strings {path} = {values}", lambda f: _replace(
            f, path, data, dtype=h5py.string_dtype()
        )
    # kind == "speed": physically impossible speed records
    data = draw.draw(
        st.sampled_from(
            [
                ("speed/speed_m_s", np.array([20.0, -1.0, 21.0])),
                ("speed/speed_m_s", np.array([20.0, 0.0, 21.0])),
                ("speed/time_s", np.array([0.0, 1.0, 1.0])),
                ("speed/time_s", np.array([0.5, 1.0, 2.0])),
            ]
        )
    )
    path, values = data
    unit = UNITS[path]

    def speed(f: h5py.File) -> None:
        _replace(f, path, values)
        f[path].attrs["units"] = unit

    return f"{path} = {values}", speed


@FUZZ
@given(draw=st.data())
def test_structural_corruption_raises_a_clear_error(draw: st.DataObject) -> None:
    description, mutate = _mutations(draw)
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.h5"
        path.write_bytes(bytes(512) + BASE_BYTES[512:])  # unsealed: exercise the parser
        with h5py.File(path, "r+") as file:
            mutate(file)
        with pytest.raises(MeasuredDataError) as info:
            load_run(path)
    assert str(path) in str(info.value), description
    assert type(info.value) is MeasuredDataError


def test_an_unsealed_unchanged_file_still_loads() -> None:
    """Control for the fuzz above: zeroing the user block alone is not a corruption."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.h5"
        path.write_bytes(bytes(512) + BASE_BYTES[512:])
        assert load_run(path).content_digest() == BASE_RUN.content_digest()


@FUZZ
@given(fraction=st.floats(0.0, 0.9999), sealed=st.booleans())
def test_truncated_files_raise(fraction: float, sealed: bool) -> None:
    data = BASE_BYTES if sealed else bytes(512) + BASE_BYTES[512:]
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.h5"
        path.write_bytes(data[: int(fraction * len(data))])
        with pytest.raises(MeasuredDataError, match=r"run\.h5"):
            load_run(path)


@settings(max_examples=100, deadline=None)
@given(position=st.integers(0, len(BASE_BYTES) - 1), mask=st.integers(1, 255))
def test_flipped_bytes_are_detected_or_harmless(position: int, mask: int) -> None:
    data = bytearray(BASE_BYTES)
    data[position] ^= mask
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / "run.h5"
        path.write_bytes(bytes(data))
        try:
            run = load_run(path)
        except MeasuredDataError as error:
            assert "run.h5" in str(error)
        else:  # only bytes that carry no content (user-block padding) may change silently
            assert run.content_digest() == BASE_RUN.content_digest()
            assert position < 512


@pytest.mark.parametrize(
    "content", [b"", b"hello, world\n", b"\x89HDF\r\n\x1a\n" + bytes(100), bytes(4096)]
)
def test_files_that_are_not_runs(content: bytes, tmp_path: Path) -> None:
    path = tmp_path / "run.h5"
    path.write_bytes(content)
    with pytest.raises(MeasuredDataError, match=r"run.h5: "):
        load_run(path)


def test_an_hdf5_file_of_another_kind(tmp_path: Path) -> None:
    path = tmp_path / "other.h5"
    with h5py.File(path, "w") as file:
        file.create_dataset("x", data=np.arange(3))
    with pytest.raises(MeasuredDataError, match=r"not a measured-run file: attribute format"):
        load_run(path)
