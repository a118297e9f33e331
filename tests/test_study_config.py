"""Tests of susp_bo.study_config: the example, validation messages, paths, round trip."""

from __future__ import annotations

import dataclasses
import textwrap
from pathlib import Path

import pytest

import susp_bo.study_config as study_config
import susp_bo.study_sections as study_sections
from susp_bo.rig.catalog import rig_path
from susp_bo.study_config import (
    BudgetConfig,
    ExecutorConfig,
    MCMCConfig,
    OutputErrorConfig,
    SearchConfig,
    SeedsConfig,
    StudyConfig,
    load_study_config,
)


def _docstring_example() -> str:
    doc = study_config.__doc__ or ""
    return textwrap.dedent(doc.split("::\n\n", 1)[1])


@pytest.fixture
def study_folder(tmp_path: Path) -> Path:
    """A folder with measured/ and a rig file, as the example config expects."""
    (tmp_path / "measured").mkdir()
    (tmp_path / "rigs").mkdir()
    (tmp_path / "rigs" / "my_trailer.toml").write_text("# a rig\n")
    return tmp_path


def _write(folder: Path, text: str) -> Path:
    path = folder / "study.toml"
    path.write_text(text, encoding="utf-8")
    return path


def _example_with_rig_path(folder: Path) -> Path:
    # the shipped rig may not be in this checkout: point the example at a rig file instead
    text = _docstring_example().replace('rig = "hst_trailer"', 'rig = "rigs/my_trailer.toml"')
    return _write(folder, text)


def test_docstring_example_loads_with_every_value(study_folder: Path) -> None:
    config = load_study_config(_example_with_rig_path(study_folder))
    assert config == StudyConfig(
        rig=str(study_folder / "rigs" / "my_trailer.toml"),
        data=study_folder / "measured",
        out=study_folder / "results" / "trailer",
        parameters=("secondary_vertical_damping", "primary_vertical_stiffness"),
        budget=BudgetConfig(max_evaluations=120, initial_design=40, batch_size=8, check_points=8),
        seeds=SeedsConfig(calibration=0, mcmc=1),
        executor=ExecutorConfig(workers=8),
        mcmc=MCMCConfig(chains=512, draws=2000, warmup=500, sampler="auto"),
        output_error=OutputErrorConfig(model="unpaired", sigma="estimate", sensor_noise_m_s2=0.005),
        search=SearchConfig(local=True, hunt=0.0),
    )


def test_allowed_values_agree_with_the_calibration_package() -> None:
    """The config repeats two lists of names (it does not import torch): they must agree."""
    import typing

    from susp_bo.calibration.sampling import SAMPLERS
    from susp_bo.calibration.surrogate import KernelKind

    assert study_sections._SAMPLERS == SAMPLERS
    assert typing.get_args(KernelKind) == study_sections._KERNELS


def test_readme_shows_the_docstring_example() -> None:
    readme = Path(__file__).resolve().parent.parent / "README.md"
    if not readme.is_file():
        pytest.skip("README.md is not beside the tests (installed tests)")
    assert _docstring_example().strip() in readme.read_text(encoding="utf-8")


def test_minimal_config_takes_the_defaults_and_resolves_relative_paths(
    study_folder: Path,
) -> None:
    sub = study_folder / "studies"
    sub.mkdir()
    path = _write(sub, 'rig = "../rigs/my_trailer.toml"\ndata = "../measured"\nout = "out"\n')
    config = load_study_config(path)
    assert config.data == study_folder / "measured"
    assert config.out == sub / "out"
    assert config.rig == str(study_folder / "rigs" / "my_trailer.toml")
    assert config.parameters is None
    assert config.budget == BudgetConfig()
    assert config.executor == ExecutorConfig(workers=None, scheduler=None)
    assert config.check_parameters(("a", "b")) == ("a", "b")


def test_written_config_reads_back_equal_from_another_folder(
    study_folder: Path, tmp_path_factory: pytest.TempPathFactory
) -> None:
    config = load_study_config(_example_with_rig_path(study_folder))
    config = dataclasses.replace(
        config,
        executor=ExecutorConfig(scheduler="tcp://10.0.0.5:8786"),
        output_error=OutputErrorConfig(sigma={"carbody_vertical": 0.3, "bogie_lateral": 2}),
    )
    elsewhere = tmp_path_factory.mktemp("results") / "config.toml"
    elsewhere.write_text(config.to_toml(), encoding="utf-8")
    again = load_study_config(elsewhere)
    assert again == config
    assert again.output_error.sigma == {"carbody_vertical": 0.3, "bogie_lateral": 2.0}


def test_a_config_made_in_python_with_relative_paths_is_written_absolute(
    study_folder: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A study.toml written with paths relative to the current folder was read back
    against its own folder (run_study writes ``with_absolute_paths()``)."""
    monkeypatch.chdir(study_folder)
    config = StudyConfig(rig="rigs/my_trailer.toml", data="measured", out="results")
    written = tmp_path / "elsewhere" / "study.toml"
    written.parent.mkdir()
    written.write_text(config.with_absolute_paths().to_toml(), encoding="utf-8")
    again = load_study_config(written)
    assert again.data == study_folder / "measured"
    assert again.out == study_folder / "results"
    assert Path(again.rig) == study_folder / "rigs" / "my_trailer.toml"
    shipped = StudyConfig(rig="hst_trailer", data="measured", out="results")
    assert shipped.with_absolute_paths().rig == "hst_trailer"  # a name stays a name


_PARAMETERS_LINE = 'parameters = ["secondary_vertical_damping", "primary_vertical_stiffness"]'
_RIG_LINE = 'rig = "rigs/my_trailer.toml"'
BAD_EDITS = [
    (
        "sensor_noise_m_s2 = 0.005",
        "sensor_noise_m_s2 = -0.1",
        r"output_error\.sensor_noise_m_s2: -0\.1 is not allowed; expected a number >= 0",
    ),
    (
        "batch_size = 8",
        "batch_sise = 8",
        r"budget\.batch_sise: unknown key \(did you mean 'batch_size'",
    ),
    ("[mcmc]", "[mcmcm]", r"mcmcm: unknown key \(did you mean 'mcmc'\?\)"),
    (
        "batch_size = 8",
        "batch_size = 0",
        r"budget\.batch_size: 0 is not allowed; expected an integer >= 1",
    ),
    ("batch_size = 8", "batch_size = 2.5", r"budget\.batch_size: 2\.5 is not allowed"),
    (
        "initial_design = 40",
        "initial_design = 400",
        r"max_evaluations: 120 .* >= budget\.initial_design \(400\)",
    ),
    ("mcmc = 1", "mcmc = -1", r"seeds\.mcmc: -1 is not allowed; expected an integer >= 0"),
    ("workers = 8", "workers = true", r"executor\.workers: True is not allowed"),
    (
        "# scheduler",
        "scheduler",
        r"executor: workers = 8 and scheduler = 'tcp://sch.* not allowed together",
    ),
    (
        'sigma = "estimate"',
        "sigma = -0.2",
        r"output_error\.sigma: -0\.2 is not allowed; expected a finite",
    ),
    (
        'sigma = "estimate"',
        "sigma = { carbody_vertical = 0 }",
        r"sigma\.carbody_vertical: 0 is not allowed",
    ),
    ("warmup = 500", "warmup = -5", r"mcmc\.warmup: -5 is not allowed"),
    (
        'data = "measured"',
        'data = "nowhere"',
        r"data: 'nowhere' is not allowed; no folder at .*nowhere",
    ),
    (_RIG_LINE, 'rig = "no_such_rig"', r"rig: 'no_such_rig' is not allowed; shipped rigs are \["),
    (
        _RIG_LINE,
        'rig = "rigs/missing.toml"',
        r"rig: 'rigs/missing\.toml' is not allowed; no rig file",
    ),
    (
        _PARAMETERS_LINE,
        'parameters = "yaw_damping"',
        r"parameters: 'yaw_damping' is not allowed; expected a",
    ),
    (_PARAMETERS_LINE, "parameters = []", r"parameters: \[\] is not allowed"),
    ('out = "results/trailer"', "", r"out: missing"),
    ("[budget]", "budget = 3\n[budgets]", r"budgets: unknown key \(did you mean 'budget'\?\)"),
    ('sigma = "estimate"', "sigma = [", r"not valid TOML"),
    ("local = true", "local = 1", r"search\.local: 1 is not allowed; expected true or false"),
    ("local = true", "locale = true", r"search\.locale: unknown key \(did you mean 'local'"),
    ("basins = true", 'basins = "yes"', r"search\.basins: 'yes' is not allowed; expected true"),
    (
        "refine_optimism = 0.0",
        "refine_optimism = -1",
        r"search\.refine_optimism: -1 is not allowed; expected a finite number >= 0",
    ),
    (
        "refine_optimism = 0.0",
        "refine_optimism = nan",
        r"search\.refine_optimism: nan is not allowed; expected a finite number >= 0",
    ),
    (
        'kernel = "matern"',
        'kernel = "rbf"',
        r"search\.kernel: 'rbf' is not allowed; expected one of \"matern\", \"additive_pairs\"",
    ),
    (
        "kernel_switch = true",
        'kernel_switch = "no"',
        r"search\.kernel_switch: 'no' is not allowed; expected true or false",
    ),
    (
        "hunt = 0.0",
        "hunt = -3",
        r"search\.hunt: -3 is not allowed; expected a finite number >= 0 \(0: no hunt; omit it",
    ),
    ("hunt = 0.0", 'hunt = "yes"', r"search\.hunt: 'yes' is not allowed; expected a finite"),
    (
        'sampler = "auto"',
        'sampler = "nuts"',
        r"mcmc\.sampler: 'nuts' is not allowed; expected one of \"random_walk\", \"hmc\", \"auto\"",
    ),
]


@pytest.mark.parametrize(("old", "new", "message"), BAD_EDITS)
def test_bad_configs_name_the_file_field_value_and_allowed(
    study_folder: Path, old: str, new: str, message: str
) -> None:
    path = _example_with_rig_path(study_folder)
    text = path.read_text(encoding="utf-8")
    assert old in text
    path.write_text(text.replace(old, new, 1), encoding="utf-8")
    with pytest.raises(ValueError, match=message) as raised:
        load_study_config(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_a_hunt_without_the_basin_phase_is_refused(study_folder: Path) -> None:
    """The hunt is a step of the basin phase: asked for without it, it would do nothing."""
    path = _example_with_rig_path(study_folder)
    text = path.read_text(encoding="utf-8")
    text = text.replace("basins = true", "basins = false", 1).replace("hunt = 0.0", "hunt = 3", 1)
    text = text.replace("local = true", "local = false", 1)  # only the basins rule is broken
    path.write_text(text, encoding="utf-8")
    message = r"search: hunt = 3 and basins = false are not allowed together; the hunt is part of"
    with pytest.raises(ValueError, match=message) as raised:
        load_study_config(path)
    assert str(raised.value).startswith(f"{path}: ")
    path.write_text(text.replace("hunt = 3", "hunt = 0.0", 1), encoding="utf-8")
    assert load_study_config(path).search.hunt == 0.0
    # omitted, it is the default (3 where there is no local phase): no refusal
    omitted = "\n".join(line for line in text.splitlines() if not line.startswith("hunt ="))
    path.write_text(omitted, encoding="utf-8")
    assert load_study_config(path).search.hunt is None


def test_a_hunt_with_the_local_phase_is_refused(study_folder: Path) -> None:
    """The hunt runs in a search over C_w; with the local phase it would do nothing."""
    path = _example_with_rig_path(study_folder)
    text = path.read_text(encoding="utf-8")
    assert "local = true" in text
    path.write_text(text.replace("hunt = 0.0", "hunt = 3", 1), encoding="utf-8")
    message = r"search: hunt = 3 and local = true are not allowed together; the hunt runs in"
    with pytest.raises(ValueError, match=message) as raised:
        load_study_config(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_check_parameters_names_unknown_and_allowed(study_folder: Path) -> None:
    config = load_study_config(_example_with_rig_path(study_folder))
    allowed = ("primary_vertical_stiffness", "secondary_vertical_damping", "yaw_damping")
    assert config.check_parameters(allowed) == (
        "secondary_vertical_damping",
        "primary_vertical_stiffness",
    )
    with pytest.raises(ValueError, match=r"\['secondary_vertical_damping'\] not in .* allowed"):
        config.check_parameters(("primary_vertical_stiffness",))


@pytest.mark.parametrize(
    ("name", "hint"),
    [
        (
            "yaw_damper_damping@bogie_front_lef",
            "(parameter 'yaw_damper_damping@bogie_front_lef': unknown component 'bogie_front_lef' "
            "of yaw_damper_damping (did you mean 'bogie_front_left'?); valid components: "
            "bogie_front_left, bogie_front_right, bogie_rear_left, bogie_rear_right)",
        ),
        ("carbody_mass@bogie_front", "'carbody_mass' has no per-component form"),
        (
            "yaw_damper_damping@bogie_front_left",
            "is a valid per-component name, but the rig calibrates it only with an entry of "
            "its own: [[calibration.parameters]] name = 'yaw_damper_damping@bogie_front_left'",
        ),
        ("yaw_damper_dampng", "(did you mean 'yaw_damper_damping'?)"),
    ],
    ids=["component-typo", "no-component-form", "not-calibrated", "plain-typo"],
)
def test_a_study_parameter_outside_the_calibration_set_says_what_is_wrong(
    name: str, hint: str
) -> None:
    # a misspelled per-component name got the generic "not in the calibration set" only
    config = StudyConfig(rig="hst_trailer", data=Path("d"), out=Path("o"), parameters=(name,))
    allowed = ("primary_vertical_stiffness", "yaw_damper_damping")
    with pytest.raises(ValueError) as raised:
        config.check_parameters(allowed)
    message = str(raised.value)
    assert message.startswith(f"parameters: [{name!r}] not in the calibration set")
    assert hint in message
    assert message.endswith(f"allowed: {list(allowed)}")


def test_a_study_file_that_is_not_text_is_named(tmp_path: Path) -> None:
    path = tmp_path / "study.toml"
    path.write_bytes(b"\xff\xfe\x00rig")
    with pytest.raises(ValueError, match=r"study\.toml: not a UTF-8 text file") as raised:
        load_study_config(path)
    assert str(raised.value).startswith(f"{path}: ")


def test_a_repeated_parameter_is_named() -> None:
    with pytest.raises(
        ValueError, match=r"parameters: .* is not allowed: 'b' is given more than once"
    ):
        StudyConfig(
            rig="hst_trailer", data=Path("d"), out=Path("o"), parameters=("a", "b", "c", "b")
        )


def test_direct_construction_is_validated_too() -> None:
    with pytest.raises(ValueError, match=r"parameters: \('a', 'a'\) is not allowed"):
        StudyConfig(rig="hst_trailer", data=Path("d"), out=Path("o"), parameters=("a", "a"))
    with pytest.raises(ValueError, match=r"mcmc\.chains: 0 is not allowed"):
        MCMCConfig(chains=0)
    assert StudyConfig(rig="r", data="d", out="o").data == Path("d")  # type: ignore[arg-type]


def test_a_rig_without_calibration_parameters_cannot_be_calibrated(tmp_path: Path) -> None:
    config = StudyConfig(rig="hst_trailer", data=tmp_path, out=tmp_path / "out")
    with pytest.raises(ValueError, match=r"\[\[calibration.parameters\]\]: none given") as raised:
        config.check_parameters(())
    message = str(raised.value)
    assert message.startswith(f"rig {str(rig_path('hst_trailer'))!r}: ")
    assert "needs at least one calibration parameter" in message
