"""Every error about a row of a CSV input file cites the row's line in the file, as an editor numbers it (a header,
``#`` comments and blank lines counted), whether the reader found it (a cell that is not a number) or a check after
reading did (a probability outside [0, 1], a power table that is not monotone): ``--mu-schedule``,
``--power-table``, ``--mu-list`` and a ``[power]`` table's CSV file alike. The lines below are counted by hand from
each file's text. A table written inline in TOML has no file lines of its own: its errors keep the row's number.
"""

import pytest

from packetloss_cvx.allocation.delivery import load_power, power_model
from packetloss_cvx.cli import main
from packetloss_cvx.errors import InputError
from packetloss_cvx.model.files import load_example, read_csv_rows, save_system

HEAD = "mu1,mu2\n# exported from the link budget\n\n"           # lines 1-3: a header, a comment, a blank line


def refused(capsys, *argv: str) -> str:
    assert main([*argv, "-q"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1
    return captured.err.strip()


@pytest.mark.parametrize(("body", "message"), [
    ("0.5,0.5\n" * 4 + "0.5,1.5\n" + "0.5,0.5\n" * 5,                    # the 5th row of numbers: line 8
     "--mu-schedule: line 8: expected probabilities in [0, 1], found 1.5"),
    ("0.5,0.5\n" + "0.5,x\n" + "0.5,0.5\n" * 8,                          # the 2nd row of numbers: line 5
     "--mu-schedule: line 5: expected numbers, found '0.5,x'"),
])
def test_mu_schedule_errors_cite_the_file_line(capsys, tmp_path, body, message):
    path = tmp_path / "schedule.csv"
    path.write_text(HEAD + body)
    assert refused(capsys, "solve", "two_actuator", "--mu-schedule", str(path)).endswith(message)


@pytest.mark.parametrize(("text", "message"), [
    ("# power table\npower,mu\n\n0,0\n1,0.5\n2,0.4\n", "mu must not fall as power rises (line 6: 0.4 after 0.5)"),
    ("power,mu\n# measured\n0,0\n\n1,1.5\n", r"mu must lie in [0, 1] (line 5)"),
    ("power,mu\n# measured\n0,0\n1,0.5\n1,0.6\n", "powers must increase (line 5: 1 after 1)"),
    ("power,mu\n# measured\n1,0\n2,0.5\n", "the first row's power must be 0 (the delivery of a silent channel), "
                                          "found 1 (line 3)"),
    ("power,mu\n\n0,0\n1,y\n", "line 4: expected numbers, found '1,y'"),
])
def test_power_table_errors_cite_the_file_line(capsys, tmp_path, text, message):
    path = tmp_path / "power.csv"
    path.write_text(text)
    err = refused(capsys, "allocate", "two_actuator", "--protocol", "tcp", "--alpha", "8", "--power", "table",
                  "--power-table", str(path))
    assert err.endswith(f"--power-table: {message}")


def test_a_power_table_file_named_in_the_system_file_cites_its_lines(tmp_path):
    (tmp_path / "power.csv").write_text("# power table\npower,mu\n\n0,0\n1,0.5\n2,0.4\n")
    system = save_system(load_example("two_actuator"), tmp_path / "plant.toml")
    with open(system, "a") as handle:
        handle.write('\n[power]\nmodel = "table"\ntable = "power.csv"\n')
    with pytest.raises(InputError, match=r"power\.table: mu must not fall as power rises \(line 6: 0\.4 after 0\.5\)"):
        load_power(system, 2)


def test_mu_list_errors_cite_the_file_line(capsys, tmp_path):
    path = tmp_path / "points.csv"
    path.write_text(HEAD + "0.5,0.5\n0.2,1.5\n")                         # the 2nd row of numbers: line 5
    err = refused(capsys, "sweep", "two_actuator", "--mu-list", str(path))
    assert err.endswith("--mu-list: line 5: expected probabilities in [0, 1]")


def test_a_quoted_cell_over_two_lines_moves_the_next_row_down_a_line(tmp_path):
    path = tmp_path / "points.csv"
    path.write_text('mu1,"mu\n2"\n0.5,0.5\n')                              # the header spans lines 1-2
    assert read_csv_rows(path, "mu_list").lines == (3,)
    path.write_text('mu1,"mu\n2"\n0.5,0.5\n0.5,x\n')
    with pytest.raises(InputError, match="line 4: expected numbers"):
        read_csv_rows(path, "mu_list")


def test_a_table_written_inline_keeps_the_row_number():
    with pytest.raises(InputError, match=r"mu must not fall as power rises \(row 3: 0\.4 after 0\.5\)"):
        power_model("table", 1, table=[[0, 0], [1, 0.5], [2, 0.4]])
