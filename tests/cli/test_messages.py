"""User-provided text is printed literally in every message: brackets, markup-like names
and non-ASCII characters survive (rich would read ``[final]`` or ``[red]`` as markup)."""

from __future__ import annotations

import pytest

from vei.cli.main import main

NAMES = ["runs[final]", "[red]oops[/red]", "Straße_é", "a[b]c[/]"]


@pytest.mark.parametrize("name", NAMES)
def test_a_missing_scenario_folder_is_named_literally(tmp_path, capsys, name):
    folder = tmp_path / name
    code = main(["casestudy", str(folder), "--out", str(tmp_path / "out")])
    err = capsys.readouterr().err
    assert code == 2
    assert str(folder) in " ".join(err.split()) or str(folder) in err.replace("\n", ""), err
    assert not (tmp_path / "out").exists()  # a refused command writes nothing


def test_a_broken_yaml_keeps_its_brackets(tmp_path, capsys):
    spec = tmp_path / "spec[1].yaml"
    spec.write_text("design: grid\nparameters: {time_shift_s: [1, 2\n")
    code = main(["sweep", str(tmp_path), "--spec", str(spec), "--out", str(tmp_path / "o")])
    err = " ".join(capsys.readouterr().err.split())
    assert code == 2
    assert str(spec) in err, err
    assert "expected ',' or ']'" in err, err
    assert "error:" in err


def test_a_table_cell_with_markup_like_text_prints_as_written(capsys):
    from rich.table import Table

    from vei.cli.output import console

    table = Table()
    table.add_column("[bold]name[/bold]")
    table.add_row("[red]x[/red] Straße")
    console().print(table)
    out = capsys.readouterr().out
    assert "[bold]name[/bold]" in out and "[red]x[/red] Straße" in out


@pytest.mark.parametrize("width", [80, 120, 250])
def test_case_study_table_never_cuts_a_value(width):
    """At any terminal width every value of the case-study table is printed (the table is
    transposed when one row per configuration does not fit; a cell that still does not fit
    folds onto the next line, as names do at 80 columns), never cut to '…'."""
    import io

    from rich.console import Console

    from vei.cli.sim_table import summary_table

    heads = ["config", "collision", "t collision [s]", "safety index", "min gap [m]",
             "min TTC [s]", "min TTC rel [s]", "PET [s]", "max DRAC [m/s2]",
             "peak decel [m/s2]", "speed std [m/s]", "impact speed [m/s]", "injury risk",
             "verdict"]  # fmt: skip
    names = ["replay", "normal", "aggressive", "normal-cap", "aggressive-cap"]
    rows = [[n, "yes", "8.95", "0.123", "0.00", "0.456", "0.00", "1.23", "8.00", "7.89",
             "2.468", "8.76", "0.0123", f"avoided vs {n}"] for n in names]  # fmt: skip
    buf = io.StringIO()
    console = Console(file=buf, width=width, markup=False, color_system=None)
    console.print(summary_table("case study: x", heads, rows, width))
    text = buf.getvalue()
    assert "…" not in text
    if width >= 120:  # each value whole (a long one may wrap at its spaces)
        for word in (w for row in rows for value in row for w in value.split()):
            assert word in text, (word, text)
    assert max(len(line) for line in text.splitlines()) <= width
