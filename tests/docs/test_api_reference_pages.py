"""The API reference pages (docs/api/*.md, rendered by mkdocstrings; the built site is tested in test_docs_site)
list the lossy-sensor modules: every module of packetloss_cvx.sensing, the sensor description and its results."""

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def listed_modules() -> set[str]:
    return {m for page in (ROOT / "docs" / "api").glob("*.md")
            for m in re.findall(r"^::: (packetloss_cvx[\w.]*)\s*$", page.read_text(), flags=re.M)}


def test_every_sensing_module_is_on_an_api_page():
    sensing = {f"packetloss_cvx.sensing.{p.stem}" for p in (ROOT / "packetloss_cvx" / "sensing").glob("*.py")
               if p.stem != "__init__"}
    assert len(sensing) >= 7
    missing = (sensing | {"packetloss_cvx.model.sensor", "packetloss_cvx.results.sensing"}) - listed_modules()
    assert not missing


def test_the_sensing_page_is_in_the_site_navigation():
    nav = (ROOT / "mkdocs.yml").read_text()
    assert "api/sensing.md" in nav
    assert "(sensing.md)" in (ROOT / "docs" / "api" / "index.md").read_text()
