"""The icons and terminals every archive carries (xtask/src/kit/icon.rs): FMI 2.0's `model.png`
(FMI 2.0 §2.3), FMI 3.0's `terminalsAndIcons/` (FMI 3.0.2 §2.4.9) with the motor-side and the
load-side flange of docs/model.md §1 as Modelica rotational flanges.

The PNGs are read twice, by a small reader written here (chunk CRCs, zlib) and by Pillow, and
both must agree. terminalsAndIcons.xml is checked against the XSD that fmpy ships."""

from __future__ import annotations

import io
import struct
import xml.etree.ElementTree as ET
import zipfile
import zlib
from pathlib import Path

import fmpy
import pytest
from backlash_fmu.fmu import fmu_path
from fmpy.validation import validate_fmu
from lxml import etree
from PIL import Image

import archives

SCHEMA = Path(fmpy.__file__).parent / "schema" / "fmi3" / "fmi3TerminalsAndIcons.xsd"
TERMINALS = "terminalsAndIcons/terminalsAndIcons.xml"
ICON = "terminalsAndIcons/icon.png"

# FMI 3.0.2 §2.4.9.2.3: the causalities each predefined variableKind is restricted to.
KIND_CAUSALITIES = {
    kind: {"input", "output", "parameter", "calculatedParameter"} for kind in ("signal", "inflow", "outflow")
}
# The flanges of docs/model.md §1: terminal -> (terminalKind, {memberName: (variable, unit)}).
FLANGES = {
    "flange_a": ("Modelica.Mechanics.Rotational.Interfaces.Flange_a",
                 {"phi": ("theta_m", "rad"), "tau": ("tau_m", "N.m")}),
    "flange_b": ("Modelica.Mechanics.Rotational.Interfaces.Flange_b",
                 {"phi": ("theta_L", "rad"), "tau": ("tau_L", "N.m")}),
}


@pytest.fixture(params=archives.MODELS)
def model(request) -> str:
    return request.param


def entries(path: Path) -> dict[str, bytes]:
    with zipfile.ZipFile(path) as archive:
        return {name: archive.read(name) for name in archive.namelist()}


# --- PNG ------------------------------------------------------------------------------------------


def read_png(data: bytes) -> tuple[dict, bytes]:
    """The header fields and the pixels (rows top to bottom) of an 8-bit RGBA PNG whose rows use
    filter type 0 (None), as the packaging writes them; every chunk's CRC is checked, IHDR must come
    first and IEND last. Pillow, below, decodes the same files in general."""
    assert data[:8] == b"\x89PNG\r\n\x1a\n", "PNG signature"
    at, chunks = 8, []
    while at < len(data):
        (length,) = struct.unpack(">I", data[at:at + 4])
        kind, body = data[at + 4:at + 8], data[at + 8:at + 8 + length]
        (crc,) = struct.unpack(">I", data[at + 8 + length:at + 12 + length])
        assert crc == zlib.crc32(kind + body), f"CRC of {kind!r}"
        chunks.append((kind, body))
        at += 12 + length
    assert at == len(data), "bytes after the last chunk"
    assert chunks[0][0] == b"IHDR" and chunks[-1] == (b"IEND", b"")
    width, height, depth, colour, compression, filtering, interlace = struct.unpack(">IIBBBBB", chunks[0][1])
    header = dict(width=width, height=height, depth=depth, colour=colour)
    assert (depth, colour, compression, filtering, interlace) == (8, 6, 0, 0, 0), header
    raw = zlib.decompress(b"".join(body for kind, body in chunks if kind == b"IDAT"))
    stride = width * 4 + 1
    assert len(raw) == stride * height, "inflated size"
    rows = [raw[y * stride:(y + 1) * stride] for y in range(height)]
    assert {row[0] for row in rows} == {0}, "row filter types"
    return header, b"".join(row[1:] for row in rows)


def check_png(data: bytes, name: str) -> tuple[dict, bytes]:
    """`data` decodes, by the reader above and by Pillow alike, to a square RGBA image with a
    transparent corner and opaque pixels."""
    header, pixels = read_png(data)
    assert header["width"] == header["height"], f"{name}: {header}"
    with Image.open(io.BytesIO(data)) as image:
        image.load()
        assert image.mode == "RGBA" and image.size == (header["width"], header["height"]), name
        assert image.tobytes() == pixels, f"{name}: Pillow decodes other pixels"
    alpha = pixels[3::4]
    assert alpha[0] == 0, f"{name}: the background must be transparent"
    assert max(alpha) == 255, f"{name}: nothing is drawn"
    return header, pixels


def test_fmi2_archive_has_its_icon(model):
    files = entries(fmu_path(model, 2))
    assert "model.png" in files
    header, _ = check_png(files["model.png"], f"{model} model.png")
    assert header["width"] >= 32


def test_fmi3_archive_has_its_icon_and_terminals(model):
    files = entries(fmu_path(model, 3))
    assert ICON in files and TERMINALS in files
    check_png(files[ICON], f"{model} {ICON}")
    # One picture per model, whichever standard's archive it comes in.
    assert files[ICON] == entries(fmu_path(model, 2))["model.png"]


# --- terminalsAndIcons.xml ------------------------------------------------------------------------


def test_terminals_validate_against_the_schema(model):
    schema = etree.XMLSchema(file=str(SCHEMA))
    document = etree.fromstring(entries(fmu_path(model, 3))[TERMINALS])
    assert schema.validate(document), f"{model}: {schema.error_log}"


def test_terminals_are_the_two_flanges_of_the_model(model):
    """Each member names a variable of the archive's description, with a causality its kind
    allows, and the flange member it stands for: phi an angle (rad), tau a torque (N.m); the
    version matches the description's, and each terminal's image is in the archive."""
    files = entries(fmu_path(model, 3))
    description = ET.fromstring(files["modelDescription.xml"])
    variables = {v.get("name"): v for v in description.find("ModelVariables")}
    root = ET.fromstring(files[TERMINALS])
    assert root.get("fmiVersion") == description.get("fmiVersion") == "3.0"

    found = {}
    for terminal in root.find("Terminals").findall("Terminal"):
        name = terminal.get("name")
        assert terminal.get("matchingRule") == "plug", name
        members = {}
        for member in terminal.findall("TerminalMemberVariable"):
            variable = variables.get(member.get("variableName"))
            assert variable is not None, f"{name}: no variable {member.get('variableName')}"
            kind = member.get("variableKind")
            assert variable.get("causality") in KIND_CAUSALITIES[kind], f"{name}: {variable.get('name')} as {kind}"
            members[member.get("memberName")] = (variable.get("name"), variable.get("unit"))
        # Modelica's flange: the angle is a potential, the torque a flow.
        kinds = {m.get("memberName"): m.get("variableKind") for m in terminal.findall("TerminalMemberVariable")}
        assert kinds["phi"] == "signal" and kinds["tau"] in ("inflow", "outflow"), f"{name}: {kinds}"
        found[name] = (terminal.get("terminalKind"), members)

        drawn = terminal.find("TerminalGraphicalRepresentation")
        if drawn is not None:
            image = f"terminalsAndIcons/{drawn.get('iconBaseName')}.png"
            assert image in files, f"{name}: {image} is missing"
            check_png(files[image], f"{model} {image}")
    assert found == FLANGES


def test_a_positive_flange_torque_flows_into_the_fmu(model):
    """What the torque's variableKind claims, in motion: a positive `inflow` torque is delivered
    into the FMU, so from rest it turns its flange's angle forward (an `outflow` one backward);
    compared against a run without it, whatever the other inputs do."""
    files = entries(fmu_path(model, 3))
    root = ET.fromstring(files[TERMINALS])
    archive = archives.require(model, fmi=3)
    for terminal in root.find("Terminals").findall("Terminal"):
        members = {m.get("memberName"): m for m in terminal.findall("TerminalMemberVariable")}
        angle, torque = members["phi"].get("variableName"), members["tau"].get("variableName")
        sign = 1.0 if members["tau"].get("variableKind") == "inflow" else -1.0
        moved = []
        for value in (0.0, 1e-3):
            instance = archive.co_simulation()
            try:
                for k in range(10):
                    instance.step(k * 1e-4, 1e-4, **{torque: value})
                moved.append(instance.get(angle)[0])
            finally:
                instance.free()
        assert sign * (moved[1] - moved[0]) > 0, f"{terminal.get('name')}: {torque} > 0 moved {angle} by {moved}"


# --- fmpy --------------------------------------------------------------------------------------


@pytest.mark.parametrize("fmi", (2, 3))
def test_fmpy_still_validates_the_archive(model, fmi):
    assert validate_fmu(str(fmu_path(model, fmi))) == []


# --- the controller ---------------------------------------------------------------------------------


def test_the_controller_has_its_own_icon_and_no_terminal():
    """BacklashController: its own picture (not the drive train's) in both archives, and a
    terminalsAndIcons.xml with the icon and no <Terminals>: its inputs and output are signals,
    connected one by one."""
    two, three = entries(fmu_path("BacklashController", 2)), entries(fmu_path("BacklashController", 3))
    check_png(two["model.png"], "BacklashController model.png")
    assert three[ICON] == two["model.png"]
    assert three[ICON] != entries(fmu_path(archives.MODELS[0], 3))[ICON]
    schema = etree.XMLSchema(file=str(SCHEMA))
    document = etree.fromstring(three[TERMINALS])
    assert schema.validate(document), schema.error_log
    assert document.find("Terminals") is None and document.find("GraphicalRepresentation/Icon") is not None
    assert not any(name.startswith("terminalsAndIcons/flange") for name in three)
