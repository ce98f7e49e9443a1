"""A run's record (rigkit.capture.results): written by one writer, read by one reader
that refuses what rigkit never writes, and one staleness check comparing what made the
run, as whole values, with what the session holds now."""

from __future__ import annotations

import copy
import json
from dataclasses import fields, is_dataclass, replace
from pathlib import Path

import pytest
import yaml

from rigkit.capture import load_session
from rigkit.capture.model import LaserReading, Session, Target
from rigkit.capture.results import (
    _WHAT,
    RunInputs,
    RunRecord,
    changed_inputs,
    read_record,
    session_inputs,
    stale_results,
)
from rigkit.cli import main
from rigkit.pipeline.rig import RigGeometry
from rigkit.pipeline.settings import PipelineSettings
from tests.conftest import copy_session


def _edit_rig(session: Path, edit) -> Path:  # type: ignore[no-untyped-def]
    """A rig profile file: the session's own rig values, changed by ``edit(values)``."""
    values = yaml.safe_load((session / "session.yaml").read_text())["rig"]["values"]
    edit(values)
    out = session.parent / "other-rig.yaml"
    out.write_text(yaml.safe_dump(values))
    return out


def test_set_rig_to_another_lens_and_principal_point_makes_the_results_stale(
    processed_small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Only the lens (k1) and the principal point differ: the depth map was made with
    the old ones, so it is no map of the session under the new rig."""
    session = copy_session(processed_small, tmp_path)

    def lens_and_centre(values: dict) -> None:
        values["camera"]["distortion"] = {"k1": -0.05}
        values["camera"]["principal_point_px"] = [200.0, 150.0]

    assert main(["session", "set-rig", str(session), "--rig",
                 str(_edit_rig(session, lens_and_centre))]) == 0
    stale = stale_results(load_session(session)) or ""
    assert "before the rig changed" in stale and "distortion" in stale, stale
    assert "principal_points_px" in stale
    capsys.readouterr()
    assert main(["export", str(session), "--out", str(tmp_path / "out"), "--quiet"]) == 2
    err = capsys.readouterr().err.strip()
    assert "before the rig changed" in err and len(err.splitlines()) == 1
    assert not (tmp_path / "out").exists()
    assert main(["session", "show", str(session)]) == 0
    shown = capsys.readouterr().out
    assert "ready to process" in shown and "before the rig changed" in shown


@pytest.mark.parametrize("value", [1e200, -0.5, "NaN"])
def test_a_record_with_an_absurd_offset_is_one_line_everywhere(
    processed_small: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str],
    value: object
) -> None:
    """Numbers in rigkit's own results are input too: calibrate and report refuse the
    record with one line naming the file, key and value; session show calls the results
    stale for it."""
    session = copy_session(processed_small, tmp_path)
    record = session / "results" / "depth.json"
    text = record.read_text()
    data = json.loads(text)
    data["offset_depth_error_fraction"] = 0.0
    literal = "NaN" if value == "NaN" else repr(value)
    record.write_text(json.dumps(data).replace('"offset_depth_error_fraction": 0.0',
                                               f'"offset_depth_error_fraction": {literal}'))
    for argv in (["rig", "calibrate", str(session), "--out", str(tmp_path / "rig.yaml")],
                 ["report", str(session), "--out", str(tmp_path / "report")]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1, err
        assert "depth.json" in err and "offset_depth_error_fraction" in err, err
    assert not (tmp_path / "rig.yaml").exists() and not (tmp_path / "report").exists()
    assert main(["session", "show", str(session)]) == 0
    shown = capsys.readouterr().out
    assert "offset_depth_error_fraction" in shown and "process again" in shown


# -- one staleness test per recorded value ------------------------------------------------


def _other(value: object) -> object:
    """A value of the same kind that differs from ``value`` (and stays valid)."""
    if isinstance(value, bool):
        return not value
    if isinstance(value, int):
        return value + 1
    if isinstance(value, float):
        return value * 0.5 if value else 0.25
    if isinstance(value, str):
        return value + "x"
    if isinstance(value, tuple):
        return (_other(value[0]), *value[1:]) if value else ("x",)
    if value is None:
        return 1.0
    if is_dataclass(value) and not isinstance(value, type):
        first = fields(value)[0].name
        return replace(value, **{first: _other(getattr(value, first))})
    raise AssertionError(f"no other value for {value!r}")


RIG_EDITS = {
    "focal_px": lambda v: v["camera"]["focal_length"].update(px=4000.0),
    "baseline_lr_m": lambda v: v["baselines"]["C_lr"].update(value_m=2.5),
    "baseline_lb_m": lambda v: v["baselines"]["C_lb"].update(value_m=2.5),
    "distortion": lambda v: v["camera"].update(distortion={"k1": -0.05}),
    "principal_points_px": lambda v: v["camera"].update(principal_point_px=[200.0, 150.0]),
    "one_camera": lambda v: v.update(one_camera=True),
}
"""How a rig profile changes each value of the rig the pipeline takes
(:class:`RigGeometry`); a field added to it fails the test below until it has a line."""


@pytest.fixture(scope="module")
def processed(processed_small: Path) -> Session:
    session = load_session(processed_small)
    assert stale_results(session) is None  # the run shows the session as it is
    return session


def test_every_rig_value_is_in_the_table() -> None:
    assert set(RIG_EDITS) == {f.name for f in fields(RigGeometry)}


@pytest.mark.parametrize("name", sorted(RIG_EDITS))
def test_a_changed_rig_value_makes_the_results_stale(processed: Session, name: str) -> None:
    values = copy.deepcopy(dict(processed.rig_values))
    RIG_EDITS[name](values)
    changed = replace(processed, rig_values=values)
    assert getattr(changed.rig().geometry(), name) != getattr(processed.rig().geometry(), name)
    stale = stale_results(changed, with_targets=False) or ""
    assert f"before the rig changed ({name})" in stale, stale


@pytest.mark.parametrize("name", [f.name for f in fields(PipelineSettings)])
def test_a_changed_pipeline_setting_makes_the_results_stale(processed: Session,
                                                            name: str) -> None:
    values = copy.deepcopy(dict(processed.rig_values))
    now = getattr(processed.rig().pipeline_settings(), name)
    values["pipeline"] = {**values.get("pipeline", {}), name: _other(now)}
    stale = stale_results(replace(processed, rig_values=values), with_targets=False) or ""
    assert f"before the pipeline settings changed ({name})" in stale, stale


@pytest.mark.parametrize("name", [f.name for f in fields(Target)])
def test_a_changed_target_makes_the_results_stale_but_not_its_depth(processed: Session,
                                                                    name: str) -> None:
    first = processed.targets[0]
    value = _other(getattr(first, name))
    if name == "readings":  # one reading taken back and another of the same count added
        value = (replace(first.readings[0], slope_distance_m=301.0), *first.readings[1:])
    if name == "window_px":
        value = first.window_px + 2
    changed = replace(processed, targets=(replace(first, **{name: value}),
                                          *processed.targets[1:]))
    assert "before the targets changed" in (stale_results(changed) or "")
    assert stale_results(changed, with_targets=False) is None


@pytest.mark.parametrize("name", [f.name for f in fields(LaserReading)])
def test_a_changed_laser_reading_makes_the_results_stale(processed: Session,
                                                         name: str) -> None:
    first = processed.targets[0]
    reading = first.readings[0]
    value = 301.0 if name == "slope_distance_m" else 12.0 if name == "azimuth_deg" \
        else _other(getattr(reading, name))
    target = replace(first, readings=(replace(reading, **{name: value}), *first.readings[1:]))
    changed = replace(processed, targets=(target, *processed.targets[1:]))
    assert "before the targets changed" in (stale_results(changed) or "")


@pytest.mark.parametrize("change", ["replaced", "added", "taken out"])
def test_changed_frames_make_the_results_stale(processed: Session, change: str) -> None:
    left = processed.bursts["left"]
    burst = {"replaced": (replace(left[0], sha256="0" * 64),),
             "added": (*left, replace(left[0], sha256="1" * 64)),
             "taken out": ()}[change]
    changed = replace(processed, bursts={**processed.bursts, "left": burst})
    assert "before the frames changed" in (stale_results(changed, with_targets=False) or "")


def test_every_field_of_what_made_a_run_is_compared() -> None:
    """A field added to RunInputs is compared without anyone remembering to: each field
    changed alone is named, and nothing else is."""
    base = RunInputs(frames=(("a" * 64,), ("b" * 64,), ("c" * 64,)),
                     rig=RigGeometry(4000.0, 2.0, 2.0), settings=PipelineSettings(),
                     targets=(Target("T1", (10.0, 20.0), 9),))
    assert changed_inputs(base, base) is None
    for item in fields(RunInputs):
        changed = replace(base, **{item.name: _other(getattr(base, item.name))}) \
            if item.name not in ("rig", "settings") else \
            replace(base, rig=replace(base.rig, focal_px=4001.0)) if item.name == "rig" else \
            replace(base, settings=replace(base.settings, n_points=2999))
        said = changed_inputs(base, changed) or ""
        assert said.startswith(_WHAT.get(item.name, item.name)), (item.name, said)
        assert said.count("changed") == 1


def test_the_record_reads_back_as_written(processed: Session) -> None:
    record = read_record(processed.path / "results" / "depth.json")
    assert record.inputs == session_inputs(processed)
    assert read_record_text(record.to_json(), processed.path.parent) == record


def read_record_text(text: str, folder: Path) -> RunRecord:
    path = folder / "record-copy.json"
    path.write_text(text)
    return read_record(path)
