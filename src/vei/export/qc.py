"""Run the ASAM Quality Checker for OpenSCENARIO XML on a file and read its result.

The checker (PyPI ``asam-qc-openscenarioxml``, console script ``qc_openscenario``) pins
numpy < 2, so it lives in its own tool environment (``make qc-tools`` creates
``.tools/qc``) and vei runs it as a subprocess. Its command line takes a configuration
XML (``qc_openscenario -c config.xml``) naming the input file and the result file; the
result is a ``.xqar`` XML (``CheckerResults/CheckerBundle/Checker/Issue``), parsed here.

Where the executable is found, in order: the ``qc_bin`` argument (the executable or its
folder), ``$VEI_QC_BIN`` (same; either, when given, must be right: no silent fallback),
``qc_openscenario`` on PATH, ``.tools/qc/bin`` in the
current folder or any parent of it, then in any parent of the installed package (a
source checkout with ``pip install -e``).
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from xml.sax.saxutils import quoteattr

from vei.errors import DependencyError, InputError
from vei.io.atomic import write_bytes

QC_EXECUTABLE = "qc_openscenario"
#: Issue levels of the ASAM QC result format.
LEVEL_NAMES: dict[int, str] = {1: "error", 2: "warning", 3: "information"}


@dataclass(frozen=True)
class QcIssue:
    """One issue the checker reported.

    Attributes:
        checker_id: the checker that found it.
        level: 1 error, 2 warning, 3 information.
        description: the checker's text.
        rule_uid: the ASAM rule (e.g. 'asam.net:xosc:1.0.0:xml.valid_schema').
    """

    checker_id: str
    level: int
    description: str
    rule_uid: str

    @property
    def level_name(self) -> str:
        """'error' | 'warning' | 'information'."""
        return LEVEL_NAMES.get(self.level, str(self.level))


@dataclass(frozen=True)
class QcChecker:
    """One checker's outcome: status 'completed' | 'skipped' | 'error', its summary."""

    checker_id: str
    status: str
    summary: str
    issues: tuple[QcIssue, ...]


@dataclass(frozen=True)
class QcReport:
    """The checker bundle's result for one file.

    Attributes:
        input_file: the checked file.
        result_file: the .xqar written by the checker.
        checkers: every checker's outcome, in the checker's order.
    """

    input_file: Path
    result_file: Path
    checkers: tuple[QcChecker, ...]

    @property
    def issues(self) -> tuple[QcIssue, ...]:
        """All issues, every level."""
        return tuple(i for c in self.checkers for i in c.issues)

    @property
    def internal_errors(self) -> tuple[QcChecker, ...]:
        """Checkers that crashed (status 'error')."""
        return tuple(c for c in self.checkers if c.status == "error")

    @property
    def ok(self) -> bool:
        """True when no issue of any level was found and no checker crashed."""
        return not self.issues and not self.internal_errors

    def summary(self) -> str:
        """A few lines for humans: counts, then one line per issue / crashed checker."""
        n = len(self.checkers)
        done = sum(c.status == "completed" for c in self.checkers)
        skipped = [c for c in self.checkers if c.status == "skipped"]
        lines = [
            f"{self.input_file}: {len(self.issues)} issue(s); {n} checker(s): {done} completed, "
            f"{len(skipped)} skipped, {len(self.internal_errors)} internal error(s)"
        ]
        for i in self.issues:
            lines.append(f"  [{i.level_name}] {i.checker_id}: {i.description}")
        for c in self.internal_errors:
            lines.append(f"  [internal error] {c.checker_id}: {c.summary}")
        for c in skipped:
            lines.append(f"  [skipped] {c.checker_id}: {c.summary}")
        return "\n".join(lines)


def find_qc_openscenario(qc_bin: str | Path | None = None) -> Path:
    """Path of the ``qc_openscenario`` executable (see the module doc for the search).

    Raises:
        DependencyError: not found (names ``make qc-tools`` and VEI_QC_BIN).
    """
    for given, what in (
        (qc_bin, "the given checker"),
        (os.environ.get("VEI_QC_BIN"), "VEI_QC_BIN"),
    ):
        if given:  # explicit: use it or fail, never fall back silently
            p = Path(given)
            exe = p / QC_EXECUTABLE if p.is_dir() else p
            if exe.is_file() and os.access(exe, os.X_OK):
                return exe
            raise DependencyError(
                f"{what} {exe} is not an executable qc_openscenario: run `make qc-tools` "
                "(creates .tools/qc) or fix the path"
            )
    candidates: list[Path] = []
    on_path = shutil.which(QC_EXECUTABLE)
    if on_path:
        candidates.append(Path(on_path))
    for start in (Path.cwd().resolve(), Path(__file__).resolve().parent):
        for folder in (start, *start.parents):
            candidates.append(folder / ".tools" / "qc" / "bin" / QC_EXECUTABLE)
    for c in candidates:
        if c.is_file() and os.access(c, os.X_OK):
            return c
    raise DependencyError(
        "the ASAM Quality Checker 'qc_openscenario' was not found: run `make qc-tools` "
        "(creates .tools/qc with asam-qc-openscenarioxml) or set VEI_QC_BIN to its bin folder"
    )


def parse_xqar(result_file: str | Path, input_file: str | Path | None = None) -> QcReport:
    """Parse a checker result file (.xqar) into a :class:`QcReport`."""
    from defusedxml import ElementTree as SafeET

    result_file = Path(result_file)
    try:
        root = SafeET.parse(result_file).getroot()
    except Exception as exc:
        raise InputError(f"not a readable checker result: {exc}", path=result_file) from exc
    checkers = []
    found_input = None
    for bundle in root.iter("CheckerBundle"):
        for param in bundle.findall("Param"):
            if param.get("name") == "InputFile":
                found_input = param.get("value")
        for ch in bundle.iter("Checker"):
            cid = ch.get("checkerId", "")
            issues = tuple(
                QcIssue(
                    cid,
                    int(iss.get("level", "1")),
                    iss.get("description", ""),
                    iss.get("ruleUID", ""),
                )
                for iss in ch.iter("Issue")
            )
            checkers.append(QcChecker(cid, ch.get("status", ""), ch.get("summary", ""), issues))
    if not checkers:
        raise InputError("no checker results in the file", path=result_file)
    inp = Path(input_file) if input_file is not None else Path(found_input or "")
    return QcReport(inp, result_file, tuple(checkers))


def run_qc_openscenario(
    xosc: str | Path,
    *,
    result_file: str | Path | None = None,
    qc_bin: str | Path | None = None,
    timeout_s: float = 120.0,
) -> QcReport:
    """Run the ASAM OpenSCENARIO XML checker bundle on ``xosc`` and return its report.

    Args:
        xosc: the .xosc to check (its LogicFile, if any, is read relative to it).
        result_file: where to keep the .xqar (default: ``<xosc name>.xqar`` in a new
            temporary folder, never beside the input).
        qc_bin: the executable or its folder (default: see :func:`find_qc_openscenario`).
        timeout_s: wall-clock limit [s].

    Raises:
        InputError: the file does not exist. DependencyError: no checker, or it failed
        to run (exit status, timeout) without writing a result.
    """
    xosc = Path(xosc).resolve()
    if not xosc.is_file():
        raise InputError("file not found", path=xosc)
    exe = find_qc_openscenario(qc_bin)
    if result_file:
        result = Path(result_file).resolve()
    else:
        result = Path(tempfile.mkdtemp(prefix="vei-qc-result-")) / f"{xosc.name}.xqar"
    result.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="vei-qc-") as tmp:
        tmp_result = Path(tmp) / "result.xqar"
        cfg = Path(tmp) / "config.xml"
        cfg.write_text(
            '<?xml version="1.0" encoding="UTF-8" standalone="no"?>\n<Config>\n'
            f'  <Param name="InputFile" value={quoteattr(str(xosc))} />\n'
            '  <CheckerBundle application="xoscBundle">\n'
            f'    <Param name="resultFile" value={quoteattr(str(tmp_result))} />\n'
            "  </CheckerBundle>\n</Config>\n",
            encoding="utf-8",
        )
        try:
            proc = subprocess.run(
                [str(exe), "-c", str(cfg)],
                cwd=tmp,
                capture_output=True,
                text=True,
                timeout=timeout_s,
                check=False,
            )
        except subprocess.TimeoutExpired as exc:
            raise DependencyError(f"{exe} did not finish within {timeout_s:g} s") from exc
        if proc.returncode != 0 or not tmp_result.is_file():
            tail = (proc.stderr or proc.stdout or "").strip().splitlines()[-5:]
            raise DependencyError(
                f"{exe} failed (exit status {proc.returncode}): " + " | ".join(tail)
            )
        write_bytes(result, tmp_result.read_bytes())
    return parse_xqar(result, xosc)
