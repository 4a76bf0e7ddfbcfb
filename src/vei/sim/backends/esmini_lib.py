"""ctypes binding to esmini's C library (``libesminiLib.so``), the subset vei uses.

Structures and signatures follow esmini 3.6's ``include/esminiLib.hpp`` (and esmini's own
ctypes examples). esmini keeps one scenario in global state per process: an
:class:`EsminiSession` is that scenario, and opening a second one while the first is
open is a :class:`~vei.errors.BackendError` (close it first). Every call's return code is
checked; a failure raises BackendError naming the call, the object and the tail of
esmini's log (its log goes to the file given, never into the current folder; its console
output is switched off and what it prints while loading is captured, not shown).
"""

from __future__ import annotations

import contextlib
import ctypes as ct
import os
import sys
import tempfile
import threading
from collections.abc import Iterator, Sequence
from pathlib import Path

from vei.errors import BackendError

#: esmini object types (Entities.hpp Object::Type) and vehicle categories used by vei.
OBJECT_TYPE_VEHICLE = 1
OBJECT_TYPE_PEDESTRIAN = 2
CATEGORY_CAR = 0
CATEGORY_BICYCLE = 7


class ObjectState(ct.Structure):
    """``SE_ScenarioObjectState`` (esminiLib.hpp): pose [m, rad], speed [m/s], box [m]."""

    _fields_ = [
        ("id", ct.c_int),
        ("model_id", ct.c_int),
        ("ctrl_type", ct.c_int),
        ("timestamp", ct.c_double),
        ("x", ct.c_double),
        ("y", ct.c_double),
        ("z", ct.c_double),
        ("h", ct.c_double),
        ("p", ct.c_double),
        ("r", ct.c_double),
        ("roadId", ct.c_uint32),
        ("junctionId", ct.c_uint32),
        ("t", ct.c_double),
        ("laneId", ct.c_int),
        ("laneOffset", ct.c_double),
        ("s", ct.c_double),
        ("speed", ct.c_double),
        ("centerOffsetX", ct.c_double),
        ("centerOffsetY", ct.c_double),
        ("centerOffsetZ", ct.c_double),
        ("width", ct.c_double),
        ("length", ct.c_double),
        ("height", ct.c_double),
        ("objectType", ct.c_int),
        ("objectCategory", ct.c_int),
        ("wheel_angle", ct.c_double),
        ("wheel_rot", ct.c_double),
        ("visibilityMask", ct.c_int),
    ]


class _Vec3(ct.Structure):
    _fields_ = [("x", ct.c_double), ("y", ct.c_double), ("z", ct.c_double)]


class BoundingBox(ct.Structure):
    """``SE_OSCBoundingBox``: centre offset (x, y, z) [m] and (width, length, height) [m]."""

    _fields_ = [("center", _Vec3), ("dimensions", _Vec3)]


_D = ct.c_double
_P = ct.POINTER(ct.c_double)
_SIGNATURES: dict[str, tuple[list, object]] = {
    "SE_SetLogFilePath": ([ct.c_char_p], None),
    "SE_InitWithArgs": ([ct.c_int, ct.POINTER(ct.c_char_p)], ct.c_int),
    "SE_StepDT": ([_D], ct.c_int),
    "SE_Close": ([], None),
    "SE_GetSimulationTime": ([], _D),
    "SE_GetNumberOfObjects": ([], ct.c_int),
    "SE_GetId": ([ct.c_int], ct.c_int),
    "SE_GetIdByName": ([ct.c_char_p], ct.c_int),
    "SE_GetObjectName": ([ct.c_int], ct.c_char_p),
    "SE_GetObjectState": ([ct.c_int, ct.POINTER(ObjectState)], ct.c_int),
    "SE_GetObjectVelocityGlobalXYZ": ([ct.c_int, _P, _P, _P], ct.c_int),
    "SE_ReportObjectPosXYH": ([ct.c_int, _D, _D, _D], ct.c_int),
    "SE_ReportObjectSpeed": ([ct.c_int, _D], ct.c_int),
    "SE_ReportObjectVel": ([ct.c_int, _D, _D, _D], ct.c_int),
    "SE_ReportObjectAcc": ([ct.c_int, _D, _D, _D], ct.c_int),
    "SE_AddObjectWithBoundingBox": (
        [ct.c_char_p, ct.c_int, ct.c_int, ct.c_int, ct.c_int]
        + [ct.c_char_p, BoundingBox, ct.c_int],
        ct.c_int,
    ),
    "SE_DeleteObject": ([ct.c_int], ct.c_int),
    "SE_GetObjectNumberOfCollisions": ([ct.c_int], ct.c_int),
    "SE_GetObjectCollision": ([ct.c_int, ct.c_int], ct.c_int),
}

_LIBS: dict[Path, ct.CDLL] = {}
_LOCK = threading.Lock()
_OPEN: EsminiSession | None = None


def load_library(path: str | Path) -> ct.CDLL:
    """The esmini library at ``path`` with vei's signatures set (loaded once per process).

    Raises:
        BackendError: the file cannot be loaded or lacks a function vei needs.
    """
    p = Path(path).resolve()
    with _LOCK:
        if p in _LIBS:
            return _LIBS[p]
        try:
            lib = ct.CDLL(str(p))
        except OSError as exc:
            raise BackendError(f"cannot load the esmini library {p}: {exc}") from exc
        for name, (args, res) in _SIGNATURES.items():
            try:
                fn = getattr(lib, name)
            except AttributeError as exc:
                raise BackendError(
                    f"{p} has no function {name}: not an esmini library (vei needs esmini >= 2.30)"
                ) from exc
            fn.argtypes = args
            fn.restype = res
        _LIBS[p] = lib
        return lib


@contextlib.contextmanager
def _captured_output(sink: Path) -> Iterator[None]:
    """Send the process's stdout/stderr (file descriptors 1, 2) to ``sink`` meanwhile.

    esmini prints its version banner with printf while it loads, whatever the options.
    """
    for stream in (sys.stdout, sys.stderr):
        with contextlib.suppress(Exception):
            stream.flush()
    libc = ct.CDLL(None)
    saved = []
    try:
        fd = os.open(sink, os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    except OSError:
        yield
        return
    try:
        for target in (1, 2):
            try:
                saved.append((target, os.dup(target)))
                os.dup2(fd, target)
            except OSError:
                pass
        yield
    finally:
        with contextlib.suppress(Exception):
            libc.fflush(None)
        for target, copy in saved:
            os.dup2(copy, target)
            os.close(copy)
        os.close(fd)


def _digest(*paths: Path, n_lines: int = 4) -> str:
    """esmini's own words from its log / console files: the error lines (else the last ones)."""
    lines: list[str] = []
    for path in paths:
        try:
            text = path.read_text(encoding="utf-8", errors="replace")
        except OSError:
            continue
        lines += [ln.strip() for ln in text.splitlines() if ln.strip()]
    errors = [ln for ln in lines if "error" in ln.lower()]
    picked = errors[-n_lines:] if errors else lines[-n_lines:]
    return " | ".join(picked) if picked else "(nothing)"


class EsminiSession:
    """One scenario loaded in esmini (through its library); close() releases it.

    Args:
        library: path of ``libesminiLib.so``.
        xosc: the OpenSCENARIO file to load.
        log_path: esmini's log file (created); what esmini prints while loading goes to
            ``<log_path>.console.txt`` beside it.
        collision: esmini's own collision detection on (``--collision``).
        extra_args: further esmini command-line options.

    Raises:
        BackendError: another session is open in this process, or esmini refuses the
        file (its return code), with the tail of its log.
    """

    def __init__(
        self,
        library: str | Path,
        xosc: str | Path,
        log_path: str | Path,
        *,
        collision: bool = True,
        extra_args: Sequence[str] = (),
    ) -> None:
        global _OPEN
        self.lib = load_library(library)
        self.xosc = Path(xosc)
        self.log_path = Path(log_path)
        self.console_path = self.log_path.with_name(self.log_path.name + ".console.txt")
        self._state = ObjectState()
        self._open = False
        if not self.xosc.is_file():
            raise BackendError(f"esmini: no scenario file {self.xosc}")
        with _LOCK:
            if _OPEN is not None:
                raise BackendError(
                    f"esmini already has a scenario open in this process ({_OPEN.xosc.name}); "
                    "esmini keeps one scenario per process: close it first"
                )
            _OPEN = self
        try:
            args = ["vei", "--headless", "--osc", str(self.xosc), "--disable_stdout"]
            args += ["--logfile_path", str(self.log_path)]
            # esmini merges trajectory vertices closer than 0.1 m by default: a slow road
            # user (vertices 1 cm apart at 0.2 m/s and 20 Hz) then lags up to 0.1 m
            args += ["--traj_filter", "0"]
            if collision:
                args.append("--collision")
            args += list(extra_args)
            argv = (ct.c_char_p * len(args))(*[a.encode() for a in args])
            self.lib.SE_SetLogFilePath(str(self.log_path).encode())
            with _captured_output(self.console_path):
                rc = self.lib.SE_InitWithArgs(len(args), argv)
            if rc != 0:
                with contextlib.suppress(Exception):
                    self.lib.SE_Close()
                raise BackendError(
                    f"esmini could not load {self.xosc} (SE_InitWithArgs returned {rc}); "
                    f"esmini says: {_digest(self.log_path, self.console_path)}"
                )
            self._open = True
        except BaseException:
            with _LOCK:
                _OPEN = None
            raise

    # ---------------------------------------------------------------- objects
    def object_id(self, name: str) -> int | None:
        """esmini's id of the entity ``name`` (None if esmini has no such entity)."""
        oid = int(self.lib.SE_GetIdByName(name.encode()))
        return oid if oid >= 0 else None

    def object_names(self) -> dict[str, int]:
        """{name: id} of every entity esmini has now."""
        out = {}
        for i in range(int(self.lib.SE_GetNumberOfObjects())):
            oid = int(self.lib.SE_GetId(i))
            raw = self.lib.SE_GetObjectName(oid)
            out[raw.decode() if raw else str(oid)] = oid
        return out

    def state(self, oid: int) -> ObjectState:
        """The object's state (a fresh copy)."""
        st = ObjectState()
        self._check(self.lib.SE_GetObjectState(oid, ct.byref(st)), "SE_GetObjectState", oid)
        return st

    def velocity(self, oid: int) -> tuple[float, float]:
        """The object's velocity in the world frame (vx, vy) [m/s]."""
        vx, vy, vz = ct.c_double(), ct.c_double(), ct.c_double()
        rc = self.lib.SE_GetObjectVelocityGlobalXYZ(oid, ct.byref(vx), ct.byref(vy), ct.byref(vz))
        self._check(rc, "SE_GetObjectVelocityGlobalXYZ", oid)
        return float(vx.value), float(vy.value)

    def report(
        self,
        oid: int,
        x_m: float,
        y_m: float,
        yaw_rad: float,
        speed_mps: float,
        velocity_mps: tuple[float, float] | None = None,
    ) -> None:
        """Place an object (pose [m, rad], speed [m/s], optional world velocity [m/s])."""
        lib = self.lib
        self._check(lib.SE_ReportObjectPosXYH(oid, x_m, y_m, yaw_rad), "SE_ReportObjectPosXYH", oid)
        self._check(lib.SE_ReportObjectSpeed(oid, speed_mps), "SE_ReportObjectSpeed", oid)
        if velocity_mps is not None:
            vx, vy = velocity_mps
            self._check(lib.SE_ReportObjectVel(oid, vx, vy, 0.0), "SE_ReportObjectVel", oid)

    def add_object(
        self,
        name: str,
        length_m: float,
        width_m: float,
        height_m: float,
        *,
        object_type: int = OBJECT_TYPE_VEHICLE,
        category: int = CATEGORY_CAR,
    ) -> int:
        """Add an externally placed object whose reference point is its box centre; its id."""
        box = BoundingBox(_Vec3(0.0, 0.0, 0.5 * height_m), _Vec3(width_m, length_m, height_m))
        oid = int(
            self.lib.SE_AddObjectWithBoundingBox(
                name.encode(), object_type, category, 0, -1, None, box, 0
            )
        )
        if oid < 0:
            raise BackendError(f"esmini could not add the object {name!r} ({self.xosc.name})")
        return oid

    def delete_object(self, oid: int) -> None:
        """Remove an object from the scenario."""
        self._check(self.lib.SE_DeleteObject(oid), "SE_DeleteObject", oid)

    def collisions(self, oid: int) -> list[int]:
        """Ids of the objects esmini finds overlapping ``oid`` now (``--collision``)."""
        n = int(self.lib.SE_GetObjectNumberOfCollisions(oid))
        return [int(self.lib.SE_GetObjectCollision(oid, i)) for i in range(max(n, 0))]

    # ---------------------------------------------------------------- time
    def step(self, dt_s: float) -> None:
        """Advance the scenario by ``dt_s`` seconds."""
        self._check(self.lib.SE_StepDT(dt_s), "SE_StepDT", None)

    @property
    def time_s(self) -> float:
        """esmini's simulation time [s]."""
        return float(self.lib.SE_GetSimulationTime())

    def close(self) -> None:
        """Close the scenario (SE_Close) and release the process-wide slot; idempotent."""
        global _OPEN
        if self._open:
            self._open = False
            with contextlib.suppress(Exception):
                self.lib.SE_Close()
        with _LOCK:
            if _OPEN is self:
                _OPEN = None

    def __enter__(self) -> EsminiSession:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _check(self, rc: int, call: str, oid: int | None) -> None:
        if not self._open:
            raise BackendError(f"esmini: {call} on a closed scenario ({self.xosc.name})")
        if rc != 0:
            what = f" for object {oid}" if oid is not None else ""
            raise BackendError(
                f"esmini: {call}{what} failed (return code {rc}) in {self.xosc.name}; "
                f"esmini says: {_digest(self.log_path, self.console_path)}"
            )


def new_log_dir() -> Path:
    """A fresh temporary folder for esmini's files (the caller removes it)."""
    return Path(tempfile.mkdtemp(prefix="vei-esmini-"))
