"""The ASAM Quality Checker run on exported scenarios (and on a broken one)."""

from __future__ import annotations

import pytest

from tests.export.conftest import AGENTS
from vei.errors import DependencyError, InputError
from vei.export.openscenario import export_openscenario
from vei.export.qc import find_qc_openscenario, parse_xqar, run_qc_openscenario


@pytest.mark.parametrize("version", ["1.0", "1.2", "1.3"])
def test_checker_reports_no_issue_on_an_export(tmp_path, run_df, straight_xodr, qc_bin, version):
    path = export_openscenario(run_df, AGENTS, tmp_path, xodr=straight_xodr, osc_version=version)
    report = run_qc_openscenario(path, qc_bin=qc_bin)
    assert report.ok, report.summary()
    assert report.result_file.name == "vei_scenario.xosc.xqar"
    assert report.result_file.parent != tmp_path  # never beside the input
    assert not list(tmp_path.glob("*.xqar"))
    ids = {c.checker_id for c in report.checkers}
    assert "check_asam_xosc_xml_valid_schema" in ids
    statuses = {c.checker_id: c.status for c in report.checkers}
    assert statuses["check_asam_xosc_xml_valid_schema"] == "completed"
    if version != "1.0":  # the reference checks start at 1.2; with the map they all run
        assert all(c.status == "completed" for c in report.checkers), report.summary()


def test_checker_finds_an_unresolvable_entity_reference(tmp_path, run_df, qc_bin):
    path = export_openscenario(run_df, AGENTS, tmp_path, osc_version="1.2")
    broken = tmp_path / "broken.xosc"
    broken.write_text(path.read_text().replace('entityRef="c1"', 'entityRef="nobody"'))
    report = run_qc_openscenario(broken, qc_bin=qc_bin)
    assert not report.ok
    assert any(
        i.checker_id == "check_asam_xosc_reference_control_resolvable_entity_references"
        and i.level == 1
        for i in report.issues
    ), report.summary()


def test_parse_xqar_reads_issues_and_statuses(tmp_path):
    xqar = tmp_path / "r.xqar"
    xqar.write_text(
        """<?xml version='1.0' encoding='UTF-8'?>
<CheckerResults version="v1.0.0-rc.1">
  <CheckerBundle name="xoscBundle" version="v1" summary="">
    <Param name="InputFile" value="/data/s.xosc"/>
    <Checker status="completed" checkerId="a" description="" summary="1 issue">
      <AddressedRule ruleUID="asam.net:xosc:1.0.0:xml.valid_schema"/>
      <Issue issueId="0" description="bad element" level="2" ruleUID="asam.net:xosc:1.0.0:xml.valid_schema"/>
    </Checker>
    <Checker status="skipped" checkerId="b" description="" summary="no map"/>
    <Checker status="error" checkerId="c" description="" summary="crashed"/>
  </CheckerBundle>
</CheckerResults>"""
    )
    report = parse_xqar(xqar)
    assert str(report.input_file) == "/data/s.xosc"
    assert [(i.checker_id, i.level_name, i.description) for i in report.issues] == [
        ("a", "warning", "bad element")
    ]
    assert [c.checker_id for c in report.internal_errors] == ["c"]
    assert not report.ok
    assert "[skipped] b: no map" in report.summary()


def test_missing_checker_and_missing_file_are_clear_errors(tmp_path, monkeypatch):
    monkeypatch.setenv("VEI_QC_BIN", str(tmp_path / "nowhere"))
    with pytest.raises(DependencyError, match="VEI_QC_BIN .*nowhere.*make qc-tools"):
        find_qc_openscenario()
    monkeypatch.delenv("VEI_QC_BIN")
    with pytest.raises(DependencyError, match="given checker"):
        find_qc_openscenario(tmp_path / "bin")
    with pytest.raises(InputError, match="file not found"):
        run_qc_openscenario(tmp_path / "none.xosc")
