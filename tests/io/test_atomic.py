import pytest

from vei.io.atomic import atomic_dir, write_json, write_text


def test_write_text_replaces_and_leaves_no_temp(tmp_path):
    target = tmp_path / "a" / "f.txt"
    write_text(target, "one")
    write_text(target, "two")
    assert target.read_text() == "two"
    assert [p.name for p in target.parent.iterdir()] == ["f.txt"]


def test_failed_write_keeps_old_content(tmp_path):
    target = tmp_path / "f.json"
    write_json(target, {"a": 1})
    with pytest.raises(ValueError):
        write_json(target, {"a": float("nan")})  # NaN is not valid JSON
    assert target.read_text().strip() == '{\n  "a": 1\n}'
    assert [p.name for p in tmp_path.iterdir()] == ["f.json"]


def test_atomic_dir_all_or_nothing(tmp_path):
    target = tmp_path / "out"
    with atomic_dir(target) as d:
        (d / "x").write_text("1")
    assert (target / "x").read_text() == "1"
    with pytest.raises(RuntimeError), atomic_dir(target) as d:
        (d / "y").write_text("2")
        raise RuntimeError("boom")
    assert sorted(p.name for p in target.iterdir()) == ["x"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


def test_outputs_get_umask_permissions_not_0600(tmp_path):
    import os

    umask = os.umask(0o022)
    try:
        path = write_text(tmp_path / "p.txt", "x")
        assert (path.stat().st_mode & 0o777) == 0o644
        with atomic_dir(tmp_path / "d") as d:
            (d / "f").write_text("1")
        assert ((tmp_path / "d").stat().st_mode & 0o777) == 0o755
    finally:
        os.umask(umask)
