"""Every command that draws takes ``--format png|pdf|svg`` and ``--dpi``; the files written are in that format
(read by their magic bytes, an independent reader) at that resolution (a PNG's pHYs chunk, parsed by hand);
``sweep --stability`` draws its figure; ``reproduce`` titles its figures in words, not the paper's labels."""

import struct

import pytest

from packetloss_cvx.cli import main
from packetloss_cvx.cli.parser import build_parser
from packetloss_cvx.errors import InputError

DRAWING = {"simulate": ["two_actuator"], "sweep": ["pendulum", "--mu-grid", "3"], "region": ["two_actuator"],
           "reproduce": []}
MAGIC = {"png": b"\x89PNG\r\n\x1a\n", "pdf": b"%PDF-"}


def png_dpi(path):
    """Dots per inch of a PNG from its pHYs chunk (pixels per metre, unit byte 1), walking the chunks."""
    data = path.read_bytes()
    assert data[:8] == MAGIC["png"]
    at = 8
    while at < len(data):
        length, kind = struct.unpack(">I4s", data[at:at + 8])
        if kind == b"pHYs":
            x, y, unit = struct.unpack(">IIB", data[at + 8:at + 17])
            assert unit == 1
            assert x == y
            return x * 0.0254
        at += 12 + length
    raise AssertionError("no pHYs chunk")


def is_format(path, fmt):
    data = path.read_bytes()
    if fmt == "svg":
        return data.lstrip().startswith(b"<?xml") and b"<svg" in data[:2000]
    return data.startswith(MAGIC[fmt])


@pytest.mark.parametrize("command", sorted(DRAWING))
def test_every_command_that_draws_takes_format_and_dpi(command):
    args = build_parser().parse_args([command, *DRAWING[command], "--format", "pdf", "--dpi", "300"])
    assert (args.format, args.dpi) == ("pdf", 300.0)
    with pytest.raises(InputError, match="--format") as info:
        build_parser().parse_args([command, *DRAWING[command], "--format", "jpeg"])
    assert "png, pdf, svg" in str(info.value).replace("'", "")


def test_sweep_writes_png_at_the_dpi_asked_and_draws_its_stability(tmp_path, capsys):
    out = tmp_path / "s"
    assert main(["sweep", "pendulum", "--mu-grid", "5", "--shared", "--stability", "--out", str(out), "--dpi", "300",
                 "-q"]) == 0
    for name in ("sweep.png", "stability.png"):
        assert png_dpi(out / name) == pytest.approx(300, abs=0.02)
    plain = tmp_path / "p"
    assert main(["sweep", "pendulum", "--mu-grid", "5", "--shared", "--out", str(plain), "-q"]) == 0
    assert png_dpi(plain / "sweep.png") == pytest.approx(120, abs=0.02)      # the default
    assert not (plain / "stability.png").exists()                           # only with --stability


@pytest.mark.parametrize("fmt", ["svg", "pdf"])
def test_sweep_and_region_write_the_format_asked(tmp_path, fmt, capsys):
    out = tmp_path / "sweep"
    assert main(["sweep", "two_actuator", "--mu-grid", "4", "--stability", "--out", str(out), "--format", fmt,
                 "-q"]) == 0
    names = {p.name for p in out.iterdir()}
    figures = {f"sweep_{k}.{fmt}" for k in ("tcp", "udp", "diff")} | {f"stability_{k}.{fmt}" for k in ("tcp", "udp")}
    assert figures <= names
    assert not any(name.endswith(".png") for name in names)
    assert all(is_format(out / name, fmt) for name in figures)
    region = tmp_path / "region"
    assert main(["region", "two_actuator", "--grid", "4", "--out", str(region), "--format", fmt, "-q"]) == 0
    assert is_format(region / f"region.{fmt}", fmt)


def test_simulate_plot_takes_format_log_axes_and_refuses_two_formats(tmp_path, capsys):
    base = ["simulate", "two_actuator", "--closed-loop", "--samples", "20", "--steps", "4", "-q"]
    assert main([*base, "--plot", str(tmp_path / "loop"), "--format", "svg", "--yscale", "log"]) == 0
    assert is_format(tmp_path / "loop.svg", "svg")
    capsys.readouterr()
    assert main([*base, "--plot", str(tmp_path / "loop.png"), "--format", "pdf"]) == 2
    assert "--format" in capsys.readouterr().err
    assert not (tmp_path / "loop.png").exists()


@pytest.mark.parametrize("dpi", ["5", "1e6", "nan"])
def test_a_dpi_out_of_range_is_refused_before_any_work(tmp_path, dpi, capsys):
    assert main(["sweep", "pendulum", "--mu-grid", "3", "--out", str(tmp_path / "s"), "--dpi", dpi, "-q"]) == 2
    assert "--dpi" in capsys.readouterr().err
    assert not (tmp_path / "s").exists()


def test_reproduce_titles_its_figures_in_words_in_the_format_asked(tmp_path, monkeypatch, capsys):
    """Titles were the paper's labels ("fig:TCP-log-cost-mixed-mult", "eq:opt_M"): now words with mathtext."""
    import packetloss_cvx.cli.reproduce as reproduce

    titles = {}
    save = reproduce.save_figure

    def recording(fig, name, **kwargs):
        titles[name] = " ".join(filter(None, [fig.get_suptitle()] + [ax.get_title() for ax in fig.axes]))
        return save(fig, name, **kwargs)

    monkeypatch.setattr(reproduce, "save_figure", recording)
    out = tmp_path / "r"
    assert main(["reproduce", "--quick", "--out", str(out), "--format", "pdf", "--dpi", "40", "--quiet"]) == 0
    assert len(titles) == 9                                  # the paper's six, ack price, region, strategy map
    for name, title in titles.items():
        assert name.endswith(".pdf")
        assert is_format(out / name, "pdf")
        assert "fig:" not in title, name
        assert "eq:" not in title, name
        assert "$" in title, name                           # the paper's symbols, in mathtext
        assert len(title.replace("\n", " ").split()) >= 5, name
