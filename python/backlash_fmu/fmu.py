"""The one driver of the packaged FMUs: FMI 2.0 and FMI 3.0, Co-Simulation and Model Exchange,
through fmpy, as an importer drives them.

    from backlash_fmu import fmu
    with fmu.Archive.of("BacklashShaft", fmi=3) as archive:
        cs = archive.co_simulation(params={"Delta": 1e-3}, early_return=True)
        cs.step(0.0, 1e-3, tau_m=1.0)
        omega_L, = cs.get("omega_L")
        cs.free()

Every instance is made with a logger that records what the FMU logs as (status, category,
message) in `messages`, so that a refused call's reason can be read back (`refused`). The
archives are the package's own (`fmu_path`), or those of the folder `$BACKLASH_FMU_DIR` (FMI 2.0
archives and their manifest `models.txt` in it, FMI 3.0 ones in its `fmi3/`), the layout
`cargo xtask fmu` writes.
"""

from __future__ import annotations

import ctypes
import os
import shutil
from pathlib import Path
from typing import Any, Callable, Iterable, NamedTuple

import numpy as np
from fmpy import extract, read_model_description
from fmpy.fmi1 import FMICallException

# A single-gap drive train's continuous states in their order (a web line has its span's tension
# T as a fifth); also the outputs that carry them. An archive reads its own (Archive.drive_states:
# a gearbox's six, docs/model.md §10).
STATES = ("theta_m", "omega_m", "theta_L", "omega_L")
# Its ten event indicators (docs/model.md §6, §12): u - g, u + g, then the damped force's surfaces
# K*(u - g) + D*u' and K*(u + g) + D*u', and the cap's D*u' - K*(u - g) and D*u' - K*(u + g), then
# bearing friction's stop_m, breakaway_m, stop_L, breakaway_L (each 1 where the plant has no such
# surface: without a damper, the cap's with contact_law = 2, a body without friction or in the
# other mode). BacklashTwoStage has 18 (docs/model.md §10). An instance reads the count from its
# description (ModelExchange.nz).
EVENT_INDICATORS = 10
# The status every refusal is answered with: fmi2Error and fmi3Error are both 3.
ERROR = 3

# The manifest beside the archives of each standard: the plants' identifiers, one a line; and the
# controllers' (BacklashController), whose archives lie beside them.
MANIFEST = "models.txt"
CONTROLLER_MANIFEST = "controllers.txt"
# The package's own archives (FMI 2.0 here, FMI 3.0 in fmi3/), packed when it was built.
PACKAGED = Path(__file__).resolve().parent / "archives"


def archive_dir() -> Path:
    """The folder of the archives: `$BACKLASH_FMU_DIR` if set, else the package's own."""
    given = os.environ.get("BACKLASH_FMU_DIR")
    return Path(given) if given else PACKAGED


def models(folder: Path | None = None, manifest: str = MANIFEST) -> tuple[str, ...]:
    """The model identifiers of the manifest in `folder` (default `archive_dir()`), in the
    packaging's order: the plants' (`models.txt`), or with `manifest=CONTROLLER_MANIFEST` the
    controllers'; () when there is none."""
    try:
        text = ((folder or archive_dir()) / manifest).read_text()
    except FileNotFoundError:
        return ()
    return tuple(line.strip() for line in text.splitlines() if line.strip())


def _path_in(folder: Path, model: str, fmi: int) -> Path:
    if fmi not in (2, 3):
        raise ValueError(f"fmi = {fmi!r}: choose 2 or 3")
    return (folder if fmi == 2 else folder / "fmi3") / f"{model}.fmu"


def fmu_path(model: str, fmi: int = 2) -> Path:
    """The FMI 2.0 (`fmi=2`) or FMI 3.0 (`fmi=3`) archive of a model identifier in
    `archive_dir()`."""
    return _path_in(archive_dir(), model, fmi)


def packaged_path(model: str, fmi: int = 2) -> Path:
    """The archive of a model identifier shipped in the package (whatever $BACKLASH_FMU_DIR says)."""
    return _path_in(PACKAGED, model, fmi)


class StepResult(NamedTuple):
    """What a Co-Simulation step answers (FMI 3.0's fmi3DoStep; an FMI 2.0 step that returns
    has run to its end: no event, no early return)."""

    event_handling_needed: bool
    terminate_simulation: bool
    early_return: bool
    last_successful_time: float


class Archive:
    """One unpacked copy of an archive and its model description. Each copy's library is a
    file of its own, so the dynamic loader gives two copies separate code and data."""

    def __init__(self, path: str | os.PathLike, unzipdir: str | os.PathLike | None = None):
        """`unzipdir`: a copy of this archive unpacked before, to use instead of unpacking it
        again (as fmpy's `unzipdir`); `remove` deletes it too."""
        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"{self.path} not found: build the archives with `cargo xtask fmu`")
        self.md = read_model_description(str(self.path))
        self.fmi = 3 if self.md.fmiVersion.startswith("3") else 2
        self.model = self.md.coSimulation.modelIdentifier
        self.unzipdir = extract(str(self.path)) if unzipdir is None else str(unzipdir)
        self.variables = {v.name: v for v in self.md.modelVariables}
        self.vr = {name: v.valueReference for name, v in self.variables.items()}
        # The drive train's continuous states in the description's order: every state but a web
        # span's tension T (the states x[:len(drive_states)] of ModelExchange's calls).
        self.drive_states = tuple(d.variable.derivative.name for d in self.md.derivatives
                                  if d.variable.derivative.name != "T")
        # Each mesh's contact mode: `contact`, or a gearbox's `contact_1`, `contact_2`.
        self.contacts = tuple(n for n, v in self.variables.items() if v.causality == "output"
                              and (n == "contact" or n.startswith("contact_")))
        self._count = 0

    @classmethod
    def of(cls, model: str, fmi: int = 2) -> "Archive":
        """The archive of a model identifier (`fmu_path`), unpacked."""
        return cls(fmu_path(model, fmi))

    def _name(self, name: str | None, kind: str) -> str:
        self._count += 1
        return name or f"{kind}{self._count}"

    def co_simulation(
        self,
        name: str | None = None,
        params: dict[str, float] | None = None,
        start_time: float = 0.0,
        *,
        initialise: bool = True,
        early_return: bool = False,
        event_mode: bool = False,
        log_everything: bool = False,
    ) -> "CoSimulation":
        """A Co-Simulation instance, `params` (parameters, start values, inputs) set before
        initialisation; initialised unless `initialise=False`. `early_return` and `event_mode`
        are FMI 3.0's earlyReturnAllowed and eventModeUsed."""
        return CoSimulation(self, self._name(name, "cs"), params, start_time, initialise=initialise,
                            early_return=early_return, event_mode=event_mode, log_everything=log_everything)

    def model_exchange(
        self, name: str | None = None, params: dict[str, float] | None = None, start_time: float = 0.0
    ) -> "ModelExchange":
        """A Model Exchange instance, initialised and in Continuous-Time Mode."""
        return ModelExchange(self, self._name(name, "me"), params, start_time)

    def remove(self) -> None:
        """Deletes the unpacked copy (its instances must be freed first)."""
        shutil.rmtree(self.unzipdir, ignore_errors=True)

    def __enter__(self) -> "Archive":
        return self

    def __exit__(self, *exc: object) -> None:
        self.remove()


# FMI 2.0's logger is variadic: the FMU logs through format "%s" with the message as the one
# variadic argument, which arrives like a sixth fixed argument on x86-64 and AArch64 Linux.
_FMI2_LOGGER = ctypes.CFUNCTYPE(
    None, ctypes.c_void_p, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_char_p, ctypes.c_char_p
)


class Instance:
    """What every instance shares: the recording logger, values by name, the inputs, refusals."""

    def __init__(self, archive: Archive, fmi_class: Any, name: str, **instantiate: Any):
        self.archive, self.vr, self.fmi = archive, archive.vr, archive.fmi
        self.messages: list[tuple[int, str, str]] = []
        self._vrs: dict[tuple[str, ...], list[int]] = {}
        md = archive.md
        interface = md.coSimulation if fmi_class.__name__.endswith("Slave") else md.modelExchange
        self.fmu = fmi_class(guid=md.guid, unzipDirectory=archive.unzipdir,
                             modelIdentifier=interface.modelIdentifier, instanceName=name)
        if self.fmi == 2:
            from fmpy.fmi2 import (
                fmi2CallbackAllocateMemoryTYPE,
                fmi2CallbackFreeMemoryTYPE,
                fmi2CallbackFunctions,
                fmi2CallbackLoggerTYPE,
            )

            def log2(env, instance, status, category, format, text):
                self.messages.append((status, category.decode(), text.decode()))

            self._logger = _FMI2_LOGGER(log2)  # kept alive as long as the instance
            self.callbacks = fmi2CallbackFunctions()
            self.callbacks.logger = ctypes.cast(self._logger, fmi2CallbackLoggerTYPE)
            self.callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(0)
            self.callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(0)
            self.fmu.instantiate(callbacks=self.callbacks)
            self._set_real, self._get_real, self._get_int = self.fmu.setReal, self.fmu.getReal, self.fmu.getInteger
            self._set_int = self.fmu.setInteger
        else:

            def log3(env, status, category, message):
                self.messages.append((status, category.decode(), message.decode()))

            # FMI 3.0.2 §2.3.1: with loggingOn = false the FMU calls no logger at all, so every
            # instance logs; `log_everything` keeps contact events and calls on too.
            everything = instantiate.pop("log_everything", False)
            self.fmu.instantiate(loggingOn=True, logMessage=log3, **instantiate)
            if not everything:
                self.fmu.setDebugLogging(False, ["logContactEvents", "logCalls"])
            self._set_real, self._get_real, self._get_int = self.fmu.setFloat64, self.fmu.getFloat64, self.fmu.getInt32
            self._set_int = self.fmu.setInt32
        self.c = self.fmu.component
        self._integers = frozenset(n for n, v in archive.variables.items() if v.type in ("Integer", "Int32"))
        inputs = [n for n, v in archive.variables.items() if v.causality == "input"]
        self.input_names = tuple(inputs)

    # --- values -------------------------------------------------------------------------------

    def refs(self, names: Iterable[str]) -> list[int]:
        """The value references of `names`, cached by the tuple of names."""
        key = tuple(names)
        found = self._vrs.get(key)
        if found is None:
            found = self._vrs[key] = [self.vr[n] for n in key]
        return found

    def set(self, values: dict[str, float]) -> None:
        """Values by name: Real (FMI 3.0: Float64) ones in one call, Integer (Int32) ones such as
        `contact_law` in another. An Integer's value must be a whole number (ValueError)."""
        if not values:
            return
        integers = {n: v for n, v in values.items() if n in self._integers}
        reals = {n: v for n, v in values.items() if n not in integers}
        if reals:
            self._set_real(self.refs(reals), [float(v) for v in reals.values()])
        if integers:
            for name, v in integers.items():
                if not float(v).is_integer():
                    raise ValueError(f"{name} is an Integer: {v!r} is not a whole number")
            self._set_int(self.refs(integers), [int(v) for v in integers.values()])

    def get(self, *names: str) -> list[float]:
        """Real (FMI 3.0: Float64) values by name, in one call."""
        return self._get_real(self.refs(names))

    def contact(self) -> int:
        """The Integer (FMI 3.0: Int32) output `contact` of a single-gap plant. A gearbox has one
        per mesh (`contacts`): ValueError."""
        if self.archive.contacts != ("contact",):
            raise ValueError(f"{self.archive.model} has a contact mode per mesh {self.archive.contacts}: "
                             "read them with contacts()")
        return self._get_int([self.vr["contact"]])[0]

    def contacts(self) -> dict[str, int]:
        """Each mesh's contact mode by name (`contact`; a gearbox's `contact_1`, `contact_2`), in
        one call."""
        names = self.archive.contacts
        return dict(zip(names, self._get_int(self.refs(names))))

    def integers(self, *names: str) -> list[int]:
        """Integer (FMI 3.0: Int32) values by name, in one call (`contact`, `sliding_m`, ...)."""
        return self._get_int(self.refs(names))

    def set_inputs(self, **inputs: float) -> None:
        """Inputs by name (tau_m, tau_L; a web line's v_in, T_in), in one call."""
        self.set(inputs)

    # --- refusals -------------------------------------------------------------------------------

    def refused(self, call: Callable[[], object], *mentions: str) -> list[str]:
        """call() must fail with fmi2Error/fmi3Error and log, under logErrors, a reason that
        names each of `mentions` (the culprit: a variable, a length); returns the new reasons.
        Raises AssertionError otherwise."""
        before = len(self.messages)
        try:
            call()
        except FMICallException as e:
            if e.status != ERROR:
                raise AssertionError(f"refused with status {e.status}, not the error status {ERROR}") from e
        else:
            raise AssertionError("the call was not refused")
        reasons = [m[2] for m in self.messages[before:] if m[1] == "logErrors" and m[0] == ERROR]
        if not any(all(w in r for w in mentions) for r in reasons):
            raise AssertionError(f"no logged reason names {mentions}: {self.messages[before:]}")
        return reasons

    def free(self) -> None:
        self.fmu.freeInstance()


class CoSimulation(Instance):
    """A Co-Simulation instance (FMU2Slave, FMU3Slave), in Step Mode once initialised."""

    def __init__(self, archive: Archive, name: str, params: dict[str, float] | None, start_time: float, *,
                 initialise: bool, early_return: bool, event_mode: bool, log_everything: bool):
        if archive.fmi == 2:
            if early_return or event_mode:
                raise ValueError("early return and Event Mode are FMI 3.0's: open the FMI 3.0 archive")
            from fmpy.fmi2 import FMU2Slave

            super().__init__(archive, FMU2Slave, name)
        else:
            from fmpy.fmi3 import FMU3Slave

            super().__init__(archive, FMU3Slave, name, eventModeUsed=event_mode,
                             earlyReturnAllowed=early_return, log_everything=log_everything)
        self.early_return, self.event_mode = early_return, event_mode
        self.params = dict(params or {})
        self.t0 = self.time = start_time
        self.initial_update = None
        if initialise:
            self.initialise(start_time)

    def initialise(self, start_time: float = 0.0) -> None:
        """Parameters and start values (variability fixed, docs/model.md §4), then
        initialisation; with FMI 3.0's eventModeUsed initialisation ends in Event Mode
        (docs/model.md §7): one fmi3UpdateDiscreteStates, then Step Mode."""
        self.t0 = self.time = start_time
        self.set(self.params)
        if self.fmi == 2:
            self.fmu.setupExperiment(startTime=start_time)
            self.fmu.enterInitializationMode()
            self.fmu.exitInitializationMode()
        else:
            self.fmu.enterInitializationMode(startTime=start_time)
            self.fmu.exitInitializationMode()
            if self.event_mode:
                self.initial_update = self.fmu.updateDiscreteStates()
                self.fmu.enterStepMode()

    def do_step(self, t: float, h: float) -> StepResult:
        """One step from the communication point t; `time` follows its last successful time."""
        if self.fmi == 2:
            self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h)
            answer = StepResult(False, False, False, t + h)
        else:
            answer = StepResult(*self.fmu.doStep(currentCommunicationPoint=t, communicationStepSize=h))
        self.time = answer.last_successful_time
        return answer

    def step(self, t: float, h: float, **inputs: float) -> StepResult:
        """The inputs given (held over the step), then one step."""
        self.set(inputs)
        return self.do_step(t, h)

    def outputs(self, names: tuple[str, ...]) -> dict[str, float]:
        """`names` and each mesh's contact mode (`contact`, a gearbox's `contact_1`, `contact_2`)
        read together, as a dict."""
        out = dict(zip(names, self.get(*names)))
        out.update(self.contacts())
        return out

    def free(self) -> None:
        """fmi2Terminate where the instance can terminate (initialised, not in error), then
        fmi2FreeInstance / fmi3FreeInstance."""
        if self.fmi == 2:
            try:
                self.fmu.terminate()
            except FMICallException:
                pass  # refused (and logged) in a state that cannot terminate; freed all the same
        self.fmu.freeInstance()


class ModelExchange(Instance):
    """A Model Exchange instance (FMU2Model, FMU3Model), initialised and in Continuous-Time
    Mode, with the calls an integrator makes. States, derivatives and nominals are the drive
    train's (Archive.drive_states: a single gap's four, STATES, or a gearbox's six); a web line's
    last, T, is set to 0 by `set_state`."""

    def __init__(self, archive: Archive, name: str, params: dict[str, float] | None, start_time: float):
        if archive.fmi == 2:
            from fmpy.fmi2 import FMU2Model

            super().__init__(archive, FMU2Model, name)
        else:
            from fmpy.fmi3 import FMU3Model

            super().__init__(archive, FMU3Model, name)
        self.nx = len(archive.md.derivatives)
        self.n_drive = len(archive.drive_states)
        self._x = (ctypes.c_double * self.nx)()
        self._dx = (ctypes.c_double * self.nx)()
        self.nz = archive.md.numberOfEventIndicators
        self._z = (ctypes.c_double * self.nz)()
        self._u = (ctypes.c_double * 2)()
        self._torques = (ctypes.c_uint * 2)(self.vr["tau_m"], self.vr["tau_L"])
        self.x_view = np.ctypeslib.as_array(self._x)
        self.set(params or {})
        self.start_time = start_time
        m = self.fmu
        if self.fmi == 2:
            m.setupExperiment(startTime=start_time)
            m.enterInitializationMode()
            m.exitInitializationMode()
            self.initial_event = m.newDiscreteStates()
            self._set_time, self._set_states = m.fmi2SetTime, m.fmi2SetContinuousStates
            self._get_derivatives, self._get_indicators = m.fmi2GetDerivatives, m.fmi2GetEventIndicators
        else:
            m.enterInitializationMode(startTime=start_time)
            m.exitInitializationMode()
            self.initial_event = m.updateDiscreteStates()
            self._set_time, self._set_states = m.fmi3SetTime, m.fmi3SetContinuousStates
            self._get_derivatives, self._get_indicators = m.fmi3GetContinuousStateDerivatives, m.fmi3GetEventIndicators
        self.initial_update = self.initial_event
        m.enterContinuousTimeMode()

    def set_torques(self, tau_m: float, tau_L: float) -> None:
        """The two torques, in one call without allocation (an integrator's hot path)."""
        self._u[0], self._u[1] = tau_m, tau_L
        if self.fmi == 2:
            self.fmu.fmi2SetReal(self.c, self._torques, 2, self._u)
        else:
            self.fmu.fmi3SetFloat64(self.c, self._torques, 2, self._u, 2)

    def set_state(self, t: float, x: Any) -> None:
        """Time and the drive train's states x[:n_drive]; a web line's T is 0."""
        n = self.n_drive
        self._set_time(self.c, t)
        self.x_view[:n] = x[:n]
        self._set_states(self.c, self._x, self.nx)

    def derivatives(self, t: float, x: Any, tau_m: float, tau_L: float) -> np.ndarray:
        """The drive train's derivatives at (t, x[:n_drive]) under the torques."""
        self.set_state(t, x)
        self.set_torques(tau_m, tau_L)
        self._get_derivatives(self.c, self._dx, self.nx)
        return np.array(self._dx[: self.n_drive])

    def indicators(self, t: float, x: Any) -> np.ndarray:
        """The event indicators at (t, x[:n_drive]): a single gap's u - g, u + g, the damper's four
        and friction's four (EVENT_INDICATORS); a gearbox's six per mesh and two per body."""
        self.set_state(t, x)
        self._get_indicators(self.c, self._z, self.nz)
        return np.array(self._z)

    def nominals(self) -> np.ndarray:
        """The drive train's state nominals."""
        out = (ctypes.c_double * self.nx)()
        self.fmu.getNominalsOfContinuousStates(out, self.nx)
        return np.array(out[: self.n_drive])

    def continuous_states(self) -> np.ndarray:
        """The drive train's states."""
        out = (ctypes.c_double * self.nx)()
        self.fmu.getContinuousStates(out, self.nx)
        return np.array(out[: self.n_drive])

    def completed_step(self) -> tuple[bool, bool]:
        """fmi2CompletedIntegratorStep / fmi3CompletedIntegratorStep: (enterEventMode,
        terminateSimulation)."""
        return self.fmu.completedIntegratorStep()

    def event_iteration(self) -> tuple:
        """Event Mode, one fmi2NewDiscreteStates / fmi3UpdateDiscreteStates, back to
        Continuous-Time Mode: the event info."""
        self.fmu.enterEventMode()
        info = self.fmu.newDiscreteStates() if self.fmi == 2 else self.fmu.updateDiscreteStates()
        self.fmu.enterContinuousTimeMode()
        return info
