"""``reproduce``: every figure of the paper with its paragraph, results.json whose numbers agree with
independent references, and the same bytes on a second run (the README runs the full one; this
runs ``--quick``)."""

import json

import numpy as np
import pytest

import packetloss_cvx as pl
from packetloss_cvx.cli import main
from packetloss_cvx.cli.reproduce_report import BEYOND_FIGURES, FIGURES, REGION_FIGURE, STRATEGY_FIGURE
from packetloss_cvx.tolerances import ACTUATOR_DP_STATIONARY_RTOL

from ..references import enumerated_radius

LABELS = list(FIGURES)


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    outs = [tmp_path_factory.mktemp(f"run{k}") for k in range(2)]
    codes = [main(["reproduce", "--out", str(out), "--quick", "--quiet"]) for out in outs]
    return codes, outs


def test_every_figure_with_its_paragraph(runs):
    codes, (out, _) = runs
    assert codes == [0, 0]
    report = (out / "report.md").read_text()
    for label in LABELS:
        png = out / f"{label.removeprefix('fig:')}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert f"## {label}" in report
        assert f"]({png.name})" in report                 # the figure is shown in the report
    assert "Table I (pendulum" in report
    assert "| theorem-2 | holds |" in report
    assert "claims.md" in report


def test_every_link_of_the_report_resolves_in_its_folder(runs):
    """The report's links went to docs/claims.md, which an installed package does not have: they now
    go to claims.md beside it (this run's audit), and every anchor names one of its sections."""
    import re

    _, (out, _) = runs
    report = (out / "report.md").read_text()
    sections = {re.sub(r"[^a-z0-9 -]", "", title.lower()).replace(" ", "-")
                for title in re.findall(r"^### (.+)$", (out / "claims.md").read_text(), flags=re.M)}
    links = re.findall(r"\]\(([^)]+)\)", report)
    assert any(link.startswith("claims.md#") for link in links)
    for link in links:
        name, _, anchor = link.partition("#")
        assert (out / name).exists(), link
        assert not anchor or anchor in sections, link


def test_deterministic(runs):
    _, (first, second) = runs
    for name in ["results.json", "report.md", "claims.md",
                 *(f"{label.removeprefix('fig:')}.png" for label in LABELS),
                 *(f"{name}.png" for name in BEYOND_FIGURES)]:
        assert (first / name).read_bytes() == (second / name).read_bytes(), name


def test_results_against_independent_references(runs, two_actuator, pendulum):
    _, (out, _) = runs
    data = json.loads((out / "results.json").read_text())
    grid = np.array(data["mixed"]["axis"])
    tcp = np.array(data["mixed"]["tcp"])
    j, i = 3, len(grid) - 1                           # tcp[j, i] = J*(mu1 = grid[i], mu2 = grid[j])
    qp = pl.solve_qp(two_actuator.with_mu([grid[i], grid[j]]), "tcp", with_gain=False, cross_check=False).cost
    assert tcp[j, i] == pytest.approx(qp, rel=1e-6)
    # the pendulum's maximiser beats its neighbours on a fine grid, evaluated by the QP twin
    nu = data["pendulum"]["maximiser"]["nu"]

    def diff(v):
        s = pendulum.with_mu([v])
        return (pl.solve_qp(s, "udp", with_gain=False, cross_check=False).cost
                - pl.solve_qp(s, "tcp", with_gain=False, cross_check=False).cost)

    assert diff(nu) >= max(diff(nu * 0.7), diff(nu * 1.4))
    # an allocation is feasible: J*(mu) <= alpha by the QP twin
    row = data["allocations"]["udp"]["1.0, 1.0"][0]
    s = two_actuator.with_mu(row["mu"])
    assert pl.solve_qp(s, "udp", with_gain=False, cross_check=False).cost <= row["alpha"] * (1 + 1e-6)
    assert set(data["verdicts"]) == set(LABELS)


def test_unwritable_out_exit_2(capsys, tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["reproduce", "--out", str(blocker / "sub"), "--quiet"]) == 2
    assert capsys.readouterr().err.startswith("packetloss-cvx: error: --out:")


def test_the_full_runs_audit_is_the_projects():
    # reproduce's claims.md is docs/claims.md's block (test_claims_doc checks that command's output
    # by value): the same number of random systems and the same seed
    from pathlib import Path

    from packetloss_cvx.cli.reproduce import SETTINGS

    doc = (Path(__file__).resolve().parents[2] / "docs" / "claims.md").read_text()
    full = SETTINGS["full"]
    assert f"audit --random {full['audit_random']} --seed {full['audit_seed']} --report" in doc
    assert full["audit_skips"] == ()


def test_report_does_not_say_theorem_2_fails_because_of_rounding():
    from packetloss_cvx.cli.reproduce_report import _cost_mixed  # noqa: PLC2701 (test of a paragraph)

    axis = np.linspace(0, 1, 3)
    tcp = np.array([[3.0, 2.0, 1.0], [2.5, 1.5, 0.9], [2.0, 1.0, 0.5]])
    udp = tcp + 0.1
    udp[2, 0] = np.nextafter(tcp[2, 0], 0)                 # rounding at a deterministic corner
    diff = udp - tcp
    diff[2, 0] = 0.0                                      # the cancellation-free J_Delta there
    text, _ = _cost_mixed({"mixed": {"axis": axis, "tcp": tcp, "udp": udp, "diff": diff}}, "tcp")
    assert "NOT every grid point" not in text
    diff[1, 1] = -1.0                                    # a real violation is still reported
    text, _ = _cost_mixed({"mixed": {"axis": axis, "tcp": tcp, "udp": udp, "diff": diff}}, "tcp")
    assert "NOT every grid point" in text


def parse_tables(report):
    """Every Markdown table of the report headed '| alpha |', as {alpha: {beta column: cell}} (read back
    from the text, independently of how it was written)."""
    tables, lines = [], report.splitlines()
    for k, line in enumerate(lines):
        if line.startswith("| alpha |"):
            head = [c.strip() for c in line.strip("|").split("|")]
            rows = {}
            for body in lines[k + 2:]:
                if not body.startswith("|"):
                    break
                cells = [c.strip() for c in body.strip("|").split("|")]
                rows[float(cells[0])] = dict(zip(head[1:], cells[1:], strict=True))
            tables.append(rows)
    return tables


def test_allocations_are_a_table_per_protocol(runs):
    """report.md listed the allocations as one long paragraph; now a table per -mult figure: a row per alpha,
    a column per beta, each cell the mu* of results.json."""
    _, (out, _) = runs
    data = json.loads((out / "results.json").read_text())
    tables = parse_tables((out / "report.md").read_text())
    assert len(tables) == 2                                          # TCP-like, then UDP-like
    for table, protocol in zip(tables, ("tcp", "udp"), strict=True):
        cells = 0
        for beta, rows in data["allocations"][protocol].items():
            for row in rows:
                mu = row["mu"]
                expected = "infeasible" if mu is None else f"({mu[0]:.3f}, {mu[1]:.3f})"
                assert table[row["alpha"]][f"beta = ({beta})"] == expected
                cells += 1
        assert cells == sum(len(r) for r in table.values())          # nothing else in the table
    paragraph = [line for line in (out / "report.md").read_text().splitlines() if "listed in the table" in line]
    assert len(paragraph) == 2
    assert all(len(p) < 1200 for p in paragraph)                       # the numbers left the paragraph


def test_a_quick_run_does_not_call_a_claim_met_on_one_level(runs):
    """--quick draws only alpha = 4.78, where the perfect-channel claim happens to hold; its report said
    "matches" where the full run (more levels) says "partly": one level is now said to be one level."""
    _, (out, _) = runs
    report = (out / "report.md").read_text()
    section = report[report.index("## fig:UDP-log-cost-mixed-mult"):]
    assert "matches at the one level drawn (alpha = 4.78); the full run draws more" in section


def test_the_region_figure_of_the_two_actuator_system_against_independent_references(runs, two_actuator):
    """Beyond the paper: region-two-actuator.png with its paragraph, and the map in results.json:
    the dp verdicts against the LMI form alone (cvxpy + Clarabel, another algorithm), the paper laws' verdicts against
    the radius of their re-designed gain enumerated over the delivery patterns."""
    from packetloss_cvx.closedloop.region import membership

    _, (out, _) = runs
    report = (out / "report.md").read_text()
    assert (out / f"{REGION_FIGURE}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"]({REGION_FIGURE}.png)" in report
    assert "at every grid point" in report
    data = json.loads((out / "results.json").read_text())
    assert data["figures"][REGION_FIGURE] == f"{REGION_FIGURE}.png"
    region = data["region"]
    axis = np.array(region["dp"]["grid"]["axis"])
    assert axis.size == data["settings"]["region_grid"]
    rng = np.random.default_rng(0)
    for j, i in rng.integers(0, axis.size, size=(5, 2)):          # rows mu2, columns mu1
        mu = np.array([axis[i], axis[j]])
        lmi = membership(two_actuator, mu, forms=("lmi",)).verdict
        if lmi != "undecided":
            assert region["dp"]["grid"]["stable"][j][i] == (lmi == "stable")
        for law in ("tcp", "udp"):
            gain = pl.closed_form(two_actuator.with_mu(mu), law).gain
            radius = enumerated_radius(two_actuator.A, two_actuator.B, gain, mu)
            assert region[law]["grid"]["radius"][j][i] == pytest.approx(radius, rel=1e-9)
            if abs(radius - 1) > 1e-6:
                assert region[law]["grid"]["stable"][j][i] == (radius < 1)


def test_the_ack_price_on_both_bases_in_the_report_and_results(runs, two_actuator):
    """The break-even price on the paper's and the attainable basis side by side (--quick: alpha = 4.78), each cell
    the number of results.json; the attainable one is the issue's 0.470 within the TCP-like design's certified gap
    (the designs themselves against an enumerated DP: tests/allocation/test_allocation_ack.py), and the paper-basis
    design's loop costs more than alpha."""
    from packetloss_cvx.allocation.ack import attainable_break_even

    _, (out, _) = runs
    data = json.loads((out / "results.json").read_text())
    both = data["ack_attainable"]
    assert both["alpha"] == [4.78]
    report = (out / "report.md").read_text()
    row = next(line for line in report.splitlines() if line.startswith("| 4.78 |") and line.count("|") == 6)
    cells = [c.strip() for c in row.strip("|").split("|")]
    paper = data["ack"]["[1.0, 1.0]"]["break_even"][data["ack"]["[1.0, 1.0]"]["alpha"].index(4.78)]
    assert cells[1:] == [f"{paper:.4g}", f"{both['break_even'][0]:.4g}", f"{both['tcp_design'][0]:.4g}",
                         f"{both['paper_design_attains'][0]:.4g}"]
    assert round(paper, 3) == 1.084                                             # the figures
    assert abs(both["break_even"][0] - 0.470) <= both["gap"] * both["tcp_design"][0] + 5e-4
    assert both["paper_design_attains"][0] > 4.78
    assert "A designer should price the link on the attainable basis" in report
    # the study in Python at the same gap gives the same number (one code path)
    udp = data["allocations"]["udp"]["1.0, 1.0"]
    again = attainable_break_even(two_actuator, [4.78], [1.0, 1.0], udp, gap=both["gap"])
    assert again["break_even"] == both["break_even"]


def test_the_tcp_allocation_figure_shows_the_attainable_designs_beside_the_papers(runs, two_actuator, tmp_path,
                                                                                  monkeypatch):
    """The TCP-like allocation figure draws the designs on the attainable cost (beta = (1, 1)) as their own line
    beside the paper's, and its paragraph lists them: each mu* meets alpha on the DP enumerated over each step's
    deliveries (tests/claims/test_claims_attainable.py), where the paper's design's loop costs more than alpha."""
    from packetloss_cvx.cli import reproduce
    from packetloss_cvx.runfolder import RunFolder

    from ..claims.test_claims_attainable import enumerated_attainable

    _, (out, _) = runs
    data = json.loads((out / "results.json").read_text())
    both = data["ack_attainable"]
    paper = {row["alpha"]: row["mu"] for row in data["allocations"]["tcp"]["1.0, 1.0"]}
    for alpha, mu, attains in zip(both["alpha"], both["mu"], both["paper_design_attains"], strict=True):
        assert enumerated_attainable(two_actuator, mu) <= alpha * (1 + 1e-9)
        assert enumerated_attainable(two_actuator, paper[alpha]) == pytest.approx(attains, rel=1e-9)
        assert attains > alpha
    report = (out / "report.md").read_text()
    section = report[report.index("## fig:TCP-log-cost-mixed-mult"):report.index("## fig:UDP-log-cost-mixed-mult")]
    lines = section.splitlines()
    head = next(k for k, line in enumerate(lines) if line.startswith("| cost bound alpha | the paper's design"))
    cells = [c.strip() for c in lines[head + 2].strip("|").split("|")]
    mu = both["mu"][0]
    assert cells[0] == "4.78"
    assert cells[1:] == [f"{both['paper_design_attains'][0]:.4g}", f"({mu[0]:.3f}, {mu[1]:.3f})",
                         f"{both['tcp_design'][0]:.4g}"]
    drawn = {}
    original = reproduce.plot_log_contour

    def spy(*args, **kwargs):
        drawn[kwargs.get("title", "")] = kwargs
        return original(*args, **kwargs)

    monkeypatch.setattr(reproduce, "plot_log_contour", spy)
    with RunFolder(tmp_path / "figures", command="test") as folder:
        reproduce.draw_figures(data, folder)
    lines = drawn[reproduce.TITLES["fig:TCP-log-cost-mixed-mult"]]["allocations"]
    assert lines[r"$\beta = (1, 1)$, attainable"] == both["mu"]
    papers = [points for label, points in lines.items() if label.endswith(", paper")]   # one per beta, (1, 1) first
    assert len(papers) == 3
    assert papers[0] == [paper[a] for a in data["settings"]["alphas"]]
    assert "attainable" not in " ".join(drawn[reproduce.TITLES["fig:UDP-log-cost-mixed-mult"]]["allocations"])
    assert "paper basis" in drawn[reproduce.TITLES["fig:TCP-log-cost-mixed-mult"]]["colorbar_label"]


def test_the_strategy_map_of_the_two_actuator_system_against_the_dare(runs, two_actuator):
    """Beyond the paper: strategy-map-two-actuator.png with its paragraph; at perfect links every strategy's optimal
    law is the full-information LQR (scipy's DARE), a tie won by zero, listed first."""
    from scipy.linalg import solve_discrete_are

    _, (out, _) = runs
    report = (out / "report.md").read_text()
    assert (out / f"{STRATEGY_FIGURE}.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert f"]({STRATEGY_FIGURE}.png)" in report
    found = json.loads((out / "results.json").read_text())["strategies"]
    assert len(found["axis"]) == json.loads((out / "results.json").read_text())["settings"]["strategy_grid"]
    P = solve_discrete_are(two_actuator.A, two_actuator.B, two_actuator.state_weights[0],
                           np.diag(two_actuator.input_weights[0]))
    dare = float(two_actuator.x0 @ P @ two_actuator.x0)
    assert all(grid[-1][-1] == pytest.approx(dare, rel=ACTUATOR_DP_STATIONARY_RTOL) for grid in found["cost"])
    assert found["winner"][-1][-1] == 0
