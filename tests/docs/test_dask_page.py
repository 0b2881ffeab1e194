"""docs/dask.md stays true: its script example has the ``__main__`` guard that ``dask="local"`` needs (a worker
process imports the script again and must not start a sweep), and runs the sweep only as the main module."""

import re
from pathlib import Path

import pytest

PAGE = Path(__file__).resolve().parents[2] / "docs" / "dask.md"


def python_blocks():
    return re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.S)


def run_as(code, name, monkeypatch):
    """Execute ``code`` as the module ``name`` with studies.sweep replaced by a recorder."""
    import packetloss_cvx.studies as studies

    calls = []
    monkeypatch.setattr(studies, "sweep", lambda *args, **kwargs: calls.append(kwargs))
    exec(compile(code, str(PAGE), "exec"), {"__name__": name})
    return calls


def test_every_local_cluster_example_is_guarded():
    local = [code for code in python_blocks() if 'dask="local"' in code]
    assert local, "docs/dask.md shows a script with dask='local'"
    for code in local:
        assert 'if __name__ == "__main__":' in code
        # the sweep is inside a function, never at the module's top level
        top = [line for line in code.splitlines() if line.startswith("result") or line.startswith("sweep(")]
        assert not top, top


@pytest.mark.parametrize(("name", "runs"), [("__mp_main__", 0), ("__main__", 1)])
def test_the_guarded_script_sweeps_only_as_the_main_module(name, runs, monkeypatch, capsys):
    """A multiprocessing worker imports the main script as ``__mp_main__``: then nothing may run."""
    (code,) = [code for code in python_blocks() if 'dask="local"' in code]
    calls = run_as(code, name, monkeypatch)
    assert len(calls) == runs
    if runs:
        assert calls[0]["dask"] == "local"


def test_the_page_states_when_dask_pays_with_a_date_and_the_machine():
    text = PAGE.read_text()
    assert "Nanny failed to start" in text
    assert re.search(r"Measured with .*benchmarks/dask_pays\.py.* on 2026-\d\d-\d\d", text, flags=re.S)
    assert "2-core" in text and "41 × 41" in text
    assert (PAGE.parent.parent / "benchmarks" / "dask_pays.py").exists()
