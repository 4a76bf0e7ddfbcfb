"""vei.report.packing: packed encounter data decodes to the original values within the
quantization step (reference decoder), NaN / None kept, the rest of the data unchanged."""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from tests.report.synthetic_report import OVERVIEW_COLUMNS, encounter
from vei.report.packing import MIN_PACKED, POINT_SCALE, STEPS, pack, read_script, script, unpack


def _columns():
    return [{"key": k, "label": lab, "fmt": f, "title": t} for k, lab, f, t in OVERVIEW_COLUMNS]


def _close(orig, got, step):
    a = np.array([np.nan if v is None else v for v in orig], float)
    b = np.array([np.nan if v is None else v for v in got], float)
    assert a.shape == b.shape
    assert np.array_equal(np.isnan(a), np.isnan(b))
    ok = ~np.isnan(a)
    # within half the quantization step (plus float rounding)
    assert np.all(np.abs(a[ok] - b[ok]) <= step / 2 + 1e-9), np.abs(a[ok] - b[ok]).max()


def test_hand_made_arrays_round_trip_within_the_step():
    x = np.array([0.0, 0.004, 0.006, 1.234, np.nan, np.nan, -5.55, 1e4, 1e4 + 0.01, 3.0])
    t = np.arange(0.0, 3.0, 0.05)
    enc = {"tracks": {"a": {"x": x, "t": t, "category": "car"}}, "id": "e1", "n": 3}
    got = unpack(pack(enc))
    assert got["id"] == "e1" and got["n"] == 3 and got["tracks"]["a"]["category"] == "car"
    # by hand: 0.004 -> 0 cm, 0.006 -> 1 cm, 1.234 -> 123 cm; NaN stays None
    assert got["tracks"]["a"]["x"][:4] == [0.0, 0.0, 0.01, 1.23]
    assert got["tracks"]["a"]["x"][4:6] == [None, None]
    _close(x, got["tracks"]["a"]["x"], 1 / STEPS["x"])
    _close(t, got["tracks"]["a"]["t"], 1 / STEPS["t"])


def test_lists_with_none_pack_too_and_short_arrays_stay_json():
    roads = {"x": [1.0, 2.5, 3.25, None, 7.0, 8.0, 9.0, None, 11.0], "y": [1.0, 2.0]}
    text = pack({"roads": roads})
    payload = zlib.decompress(text)
    assert b'"x":{"$a":' in payload and b'"y":[1.0,2.0]' in payload
    assert len(roads["y"]) < MIN_PACKED
    got = unpack(text)["roads"]
    _close(roads["x"], got["x"], 0.01)
    assert got["y"] == [1.0, 2.0]


@pytest.mark.parametrize("i", [0, 7])
def test_synthetic_encounter_round_trips_and_is_small(i):
    enc, _ = encounter(i, _columns())
    text = pack(enc)
    i_back, got = read_script(script(i, text))  # through the script's string literal
    assert i_back == i
    for aid, tr in enc["tracks"].items():
        _close(tr["x"], got["tracks"][aid]["x"], 0.01)
        _close(tr["y"], got["tracks"][aid]["y"], 0.01)
        _close(tr["t"], got["tracks"][aid]["t"], 0.001)
    _close(enc["replay"]["t"], got["replay"]["t"], 0.001)
    for c, g in zip(enc["replay"]["configs"], got["replay"]["configs"], strict=True):
        for who in ("ego", "rider"):
            for k in ("x", "y", "yaw", "speed"):
                _close(c[who][k], g[who][k], 1 / STEPS[k])
        for aid, o in c["others"].items():
            _close(o["x"], g["others"][aid]["x"], 0.01)
        _close(c["ttc_full"], g["ttc_full"], 0.001)
        _close(c["ttc"], g["ttc"], 0.001)  # rebuilt from ttc_full at the replay's times
        assert g["zone"] == [float(z) for z in c["zone"]] and g["cap"] == c["cap"]
    # the sweep's markers: reordered by x, the same set of (x, y, collision) to 1e-3
    pts, gp = enc["riskmap"]["points"], got["riskmap"]["points"]
    want = sorted(zip(np.round(pts["x"], 3), np.round(pts["y"], 3), pts["collision"], strict=True))
    have = sorted(zip(gp["x"], gp["y"], gp["collision"], strict=True))
    assert len(want) == len(have)
    assert np.allclose(np.array(want, float), np.array(have, float), atol=1 / POINT_SCALE)
    for want_row, got_row in zip(enc["summary"], got["summary"], strict=True):
        for k, v in want_row.items():
            assert got_row[k] == (pytest.approx(v, abs=1e-4) if isinstance(v, float) else v)
    # a 20th of its JSON
    from vei.report.html_report import _script_json

    assert len(text) < len(_script_json(enc)) / 10


def test_every_byte_survives_the_script_literal():
    # a payload holding every byte value, the escaped ones among them, read back
    payload = zlib.compress(bytes(range(256)) * 3 + b'\\x00"\\\n\r', 0)
    text = script(42, payload)
    assert b"\n" not in text[:-1] and b"\r" not in text and b"\0" not in text
    from vei.report import packing

    m = packing._CALL.match(text)
    assert m is not None and m.group(1) == b"42"
    back = packing._UNESCAPE_RE.sub(lambda k: packing._UNESCAPE[k.group()], m.group(2))
    assert back == payload


def test_map_layers_are_one_script_shared_by_the_encounters_with_those_layers(tmp_path):
    from tests.report.synthetic_report import synthetic_site
    from vei.report.html_site import write_site

    index, encs = synthetic_site(3)
    ring = np.array([0.0, 10.0, 10.0, 0.0, 0.0, np.nan, 20.0, 30.0, 30.0, 20.0])
    layers = {"sidewalks": {"x": ring.tolist(), "y": (ring + 5).tolist()}, "lines": None,
              "kerbs": None}  # fmt: skip
    other = {**layers, "lines": {"x": list(range(10)), "y": [0.123] * 10}}
    encounters = [
        {**e, "road_layers": lay} for e, lay in zip(encs, (layers, other, layers), strict=True)
    ]
    stats = write_site(index, iter(encounters), tmp_path / "report.html")
    enc_dir = stats.files / "enc"
    maps = sorted(p.name for p in enc_dir.glob("map_*.js"))
    assert len(maps) == 2  # encounters 0 and 2 share theirs
    got = [read_script((enc_dir / f"{i:05d}.js").read_bytes())[1] for i in range(3)]
    assert got[0]["map"] == got[2]["map"] != got[1]["map"]
    assert "road_layers" not in got[0] and "roads" not in got[0]
    key, m = read_script((enc_dir / f"map_{got[1]['map']}.js").read_bytes())
    assert key == got[1]["map"] and m["roads"] is None and m["road_layers"]["kerbs"] is None
    _close(other["lines"]["y"], m["road_layers"]["lines"]["y"], 0.01)
    _close(ring.tolist(), read_script((enc_dir / f"map_{got[0]['map']}.js").read_bytes())[1][
        "road_layers"]["sidewalks"]["x"], 0.01)  # fmt: skip
    # no map geometry (only a note): no map script
    stats = write_site(index, iter(synthetic_site(2)[1]), tmp_path / "b.html")
    assert list((stats.files / "enc").glob("map_*.js")) == []
