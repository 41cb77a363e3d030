"""The FMI 3.0 archives (target/fmu/fmi3/, docs/model.md §7) as a tool sees them, without loading
the binary: fmpy's validator, and fmpy's reading of both archives of each model, which must
describe the same variables."""

from __future__ import annotations

import xml.etree.ElementTree as ET
import zipfile
from pathlib import Path

import fmpy
import pytest
from backlash_fmu.fmu import STATES, archive_dir, fmu_path
from fmpy import read_model_description
from fmpy.validation import validate_fmu

import archives

XS = "{http://www.w3.org/2001/XMLSchema}"
# The FMI 2.0 type element of each FMI 3.0 variable element.
FMI2_TYPE = {"Float64": "Real", "Int32": "Integer"}


def fmi3_path(model: str) -> Path:
    return fmu_path(model, 3)


@pytest.fixture(params=archives.MODELS)
def model(request) -> str:
    """Each model; its FMI 3.0 archive must exist (a missing one fails, never skips)."""
    if not fmi3_path(request.param).is_file():
        pytest.fail(f"FMU archive not found: {fmi3_path(request.param)} (build with `cargo xtask fmu`)")
    return request.param


def test_the_manifests_list_the_archives_of_both_standards():
    """The models the tests run (archives.MODELS, FMI 2.0's manifest) are those packaged: each
    standard's manifest names them, in the same order, and its folder holds their archives and
    those of the controllers its second manifest names, and no other."""
    for folder in (archive_dir(), archive_dir() / "fmi3"):
        assert tuple((folder / "models.txt").read_text().split()) == archives.MODELS, folder
        controllers = tuple((folder / "controllers.txt").read_text().split())
        assert controllers == ("BacklashController",), folder
        assert sorted(path.stem for path in folder.glob("*.fmu")) == sorted(archives.MODELS + controllers), folder


def test_fmpy_validation_finds_no_problem(model):
    # Schema (fmpy's copy of the FMI 3.0 XSD), names, start values, causality and variability,
    # units, and the model structure's lists of outputs, derivatives and initial unknowns.
    assert validate_fmu(str(fmi3_path(model))) == []


def test_both_interfaces_name_the_model(model):
    md = read_model_description(str(fmi3_path(model)))
    assert md.fmiVersion == "3.0"
    assert md.modelName == model
    for interface in (md.modelExchange, md.coSimulation):
        assert interface is not None
        assert interface.modelIdentifier == model
        # fmpy stores FMI 3.0's canGetAndSetFMUState under its FMI 2.0 spelling.
        assert interface.canGetAndSetFMUstate and interface.canSerializeFMUstate
    assert not md.modelExchange.needsCompletedIntegratorStep
    cs = md.coSimulation
    assert cs.canHandleVariableCommunicationStepSize and cs.maxOutputDerivativeOrder == 1
    assert cs.hasEventMode and cs.mightReturnEarlyFromDoStep
    assert not (cs.providesIntermediateUpdate or cs.canReturnEarlyAfterIntermediateUpdate)
    # fmpy does not read providesDirectionalDerivatives of FMI 3.0: the XML itself.
    with zipfile.ZipFile(fmi3_path(model)) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    assert root.find("ModelExchange").get("providesDirectionalDerivatives") == "true"
    assert root.find("CoSimulation").get("providesDirectionalDerivatives") == "false"


def _schema_attributes(complex_type: str) -> set[str]:
    """The attributes fmpy's FMI 3.0 schema declares for an interface element, its base type's too."""
    schema = ET.parse(Path(fmpy.__file__).parent / "schema" / "fmi3" / "fmi3InterfaceType.xsd").getroot()
    types = {t.get("name"): t for t in schema.iter(f"{XS}complexType")}
    names = set()
    for name in (complex_type, "fmi3InterfaceType"):
        names |= {a.get("name") for a in types[name].iter(f"{XS}attribute")}
    return names


def test_interface_attributes_are_declared_by_the_schema(model):
    # The schema lets any attribute through on <ModelExchange> and <CoSimulation>
    # (xs:anyAttribute), so a misspelt or FMI 2.0-only capability flag would pass validation
    # unnoticed and be ignored by every importer.
    with zipfile.ZipFile(fmi3_path(model)) as zf:
        root = ET.fromstring(zf.read("modelDescription.xml"))
    for element, complex_type in (("ModelExchange", "fmi3ModelExchange"), ("CoSimulation", "fmi3CoSimulation")):
        declared = _schema_attributes(complex_type)
        assert "modelIdentifier" in declared and "canGetAndSetFMUState" in declared
        undeclared = set(root.find(element).attrib) - declared
        assert not undeclared, f"{model} <{element}>: {sorted(undeclared)} not in the FMI 3.0 schema"


def _variable(v, version: str) -> tuple:
    """What both descriptions must agree on, in FMI 2.0 terms."""
    vtype = FMI2_TYPE.get(v.type, v.type) if version == "3.0" else v.type
    as_float = (lambda x: None if x is None else float(x))
    return (
        v.name,
        v.valueReference,
        vtype,
        v.causality,
        v.variability,
        v.initial,
        as_float(v.start),
        v.unit,
        v.quantity,
        as_float(v.nominal),
        as_float(v.min),
        as_float(v.max),
        v.description,
        v.derivative.name if v.derivative is not None else None,
    )


def test_variables_equal_those_of_the_fmi2_archive(model):
    md3 = read_model_description(str(fmi3_path(model)))
    md2 = read_model_description(str(fmu_path(model)))
    assert md2.fmiVersion == "2.0"
    independent = [v for v in md3.modelVariables if v.causality == "independent"]
    assert [(v.name, v.valueReference, v.type, v.start) for v in independent] == [("time", 0, "Float64", None)]
    variables = [_variable(v, "3.0") for v in md3.modelVariables if v.causality != "independent"]
    assert variables == [_variable(v, "2.0") for v in md2.modelVariables]
    assert md3.instantiationToken != md2.guid
    assert md3.instantiationToken.startswith("{") and len(md3.instantiationToken) == 38


def test_states_derivatives_and_event_indicators(model):
    md3 = read_model_description(str(fmi3_path(model)))
    md2 = read_model_description(str(fmu_path(model)))
    pairs = [(u.variable.name, u.variable.derivative.name) for u in md3.derivatives]
    # The web line's span tension T is its fifth state (docs/model.md §8); the gearbox's
    # intermediate shaft sits between the motor and the load (§10).
    states = {
        "BacklashWeb": (*STATES, "T"),
        "BacklashTwoStage": ("theta_m", "omega_m", "theta_i", "omega_i", "theta_L", "omega_L"),
    }.get(model, STATES)
    assert pairs == [(f"der({s})", s) for s in states]
    assert pairs == [(u.variable.name, u.variable.derivative.name) for u in md2.derivatives]
    indicators = [(u.variable.name, u.variable.valueReference) for u in md3.eventIndicators]
    if model == "BacklashTwoStage":
        # Each mesh's six contact surfaces, then each body's two friction surfaces.
        surfaces = ("u_minus_g", "u_plus_g", "force_upper", "force_lower", "cap_upper", "cap_lower")
        names = [f"{s}_{j}" for j in (1, 2) for s in surfaces]
        names += [f"{kind}_{b}" for b in ("m", "i", "L") for kind in ("stop", "breakaway")]
        assert indicators == list(zip(names, range(47, 65)))
    else:
        assert indicators == [
            ("u_minus_g", 28),
            ("u_plus_g", 29),
            ("force_upper", 44),
            ("force_lower", 45),
            ("cap_upper", 46),
            ("cap_lower", 47),
            ("stop_m", 54),
            ("breakaway_m", 55),
            ("stop_L", 56),
            ("breakaway_L", 57),
        ]
    assert md2.numberOfEventIndicators == len(indicators)
    assert [u.variable.name for u in md3.outputs] == [u.variable.name for u in md2.outputs]


def test_archive_layout_and_page(model):
    with zipfile.ZipFile(fmi3_path(model)) as zf3, zipfile.ZipFile(fmu_path(model)) as zf2:
        # x86_64-linux always; `cargo xtask fmu --all-platforms` adds Windows and ARM (the FMI 3.0
        # platform tuples), each beside the same binary in the FMI 2.0 archive where it has one.
        names = set(zf3.namelist())
        required = {f"binaries/x86_64-linux/{model}.so", "documentation/index.html", "modelDescription.xml",
                    *(f"extra/org.fmi-standard.fmi-ls-ref/{name}"
                      for name in ("fmi-ls-manifest.xml", f"{model}_in.csv", f"{model}_out.csv")),
                    *(f"terminalsAndIcons/{name}"
                      for name in ("icon.png", "terminalsAndIcons.xml", "flange_a.png", "flange_b.png"))}
        optional = {f"binaries/x86_64-windows/{model}.dll", f"binaries/aarch64-linux/{model}.so"}
        assert required <= names and names <= required | optional, sorted(names)
        # The same libraries as the FMI 2.0 archive's.
        pairs = [("x86_64-linux", "linux64", "so"), ("x86_64-windows", "win64", "dll")]
        for fmi3_folder, fmi2_folder, ext in pairs:
            if f"binaries/{fmi3_folder}/{model}.{ext}" in names:
                assert zf3.read(f"binaries/{fmi3_folder}/{model}.{ext}") == zf2.read(f"binaries/{fmi2_folder}/{model}.{ext}")
        page3 = zf3.read("documentation/index.html").decode()
        page2 = zf2.read("documentation/index.html").decode()
    # Each page names its own standard and its functions only.
    assert "An FMI 3.0 FMU" in page3 and "fmi2" not in page3 and "FMI 2.0" not in page3
    assert "An FMI 2.0 FMU" in page2 and "fmi3" not in page2 and "FMI 3.0" not in page2
    assert "<td><code>time</code></td><td>independent</td>" in page3
    assert "{{" not in page3

