"""`vei import trafficmonitoring` and `vei datasets download trafficmonitoring`."""

from __future__ import annotations

import filecmp
import functools
import threading
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer

import pytest

from vei.cli.main import main
from vei.io.interaction import read_interaction


class _Quiet(SimpleHTTPRequestHandler):
    def log_message(self, format, *args):  # noqa: A002
        pass


def test_import_list(trafficmonitoring_root, capsys):
    assert (
        main(["import", "trafficmonitoring", "--root", str(trafficmonitoring_root), "--list"]) == 0
    )
    listed = capsys.readouterr().out.split()
    # one name per scenario folder entry, sorted (nine in the shared copy)
    matching = sorted(
        p.name.removesuffix("_matching.csv")
        for p in (trafficmonitoring_root / "data/measurements/matching").glob("*_matching.csv")
    )
    assert listed == matching and len(listed) >= 9
    assert "stadtmitte_12_audi_geradeaus_03" in listed


def test_import_writes_interaction_and_prints_summary(trafficmonitoring_root, tmp_path, capsys):
    out = tmp_path / "k01"
    code = main(
        [
            "import",
            "trafficmonitoring",
            "--root",
            str(trafficmonitoring_root),
            "--scenario",
            "klinikum_01_marktkauf_geradeaus",
            "--out",
            str(out),
            "--rate-hz",
            "2",
        ]
    )
    assert code == 0
    text = capsys.readouterr().out
    it = read_interaction(out)
    assert it.meta.annotation_rate_hz == 2.0
    assert "escooter: 1 track(s)" in text and "cyclist: 1 track(s)" in text
    assert f"{len(it.ego)} fixes at 10 Hz" in text
    assert "car's own camera track vs INS: median 0.2" in text


def test_import_errors_exit_2(trafficmonitoring_root, tmp_path, capsys):
    root = str(trafficmonitoring_root)
    assert (
        main(
            [
                "import",
                "trafficmonitoring",
                "--root",
                root,
                "--scenario",
                "nope",
                "--out",
                str(tmp_path / "x"),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err
    assert "unknown scenario 'nope'" in err and "Traceback" not in err
    assert main(["import", "trafficmonitoring", "--root", root, "--scenario", "nope"]) == 2
    assert "--out" in capsys.readouterr().err
    assert main(["import", "trafficmonitoring", "--root", str(tmp_path), "--list"]) == 2
    assert "data/measurements" in capsys.readouterr().err


def test_download_from_local_mirror(trafficmonitoring_root, tmp_path, capsys):
    handler = functools.partial(_Quiet, directory=str(trafficmonitoring_root))
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(
        target=httpd.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
    )
    thread.start()
    try:
        url = f"http://127.0.0.1:{httpd.server_address[1]}"
        dest = tmp_path / "tm"
        args = ["datasets", "download", "trafficmonitoring", "--dest", str(dest), "--base-url", url]
        args += ["--scenario", "audi_08_klinikum_rechtsabbiegen"]
        assert main(args) == 0
        out = capsys.readouterr().out
        assert out.count("got ") == 3 and "dataset root:" in out
        rel = "data/measurements/car_data/Record_20210209_131119'001'M200_UDP'INSSOL.csv"
        assert filecmp.cmp(dest / rel, trafficmonitoring_root / rel, shallow=False)
        assert main(args) == 0  # resume: everything already complete
        assert capsys.readouterr().out.count("skip ") == 3
        bad = ["datasets", "download", "trafficmonitoring", "--dest", str(dest), "--base-url", url]
        assert main(bad + ["--scenario", "nope_02", "--retries", "0"]) == 2
        assert "not found" in capsys.readouterr().err
    finally:
        httpd.shutdown()
        httpd.server_close()
        thread.join(timeout=5)


def test_download_list_known(capsys):
    assert main(["datasets", "download", "trafficmonitoring", "--list-known"]) == 0
    names = capsys.readouterr().out.split()
    assert len(names) == 14 and "marktkauf_04_audi_rechtsabbiegen" in names


@pytest.mark.parametrize("opt", [["--timeout-s", "0"], ["--retries", "-1"]])
def test_download_bad_options(opt, tmp_path, capsys):
    args = ["datasets", "download", "trafficmonitoring", "--dest", str(tmp_path / "d"), *opt]
    assert main(args) == 2
    assert "--timeout-s" in capsys.readouterr().err
