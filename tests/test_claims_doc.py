"""docs/claims.md's generated table matches a fresh audit (same command, same seed)."""

import re
from pathlib import Path

from packetloss_cvx.claims import audit

DOC = (Path(__file__).resolve().parent.parent / "docs" / "claims.md").read_text()


def test_doc_table_matches_fresh_audit():
    block = DOC.split("<!-- audit:begin -->")[1].split("<!-- audit:end -->")[0]
    rows = re.findall(r"^\| ([a-z0-9-]+) \| ([a-z-]+) \| (\d+) \| (\d+) \| (\d+) \|", block, flags=re.M)
    documented = {cid: (verdict, int(checked), int(violations), int(errors))
                  for cid, verdict, checked, violations, errors in rows}
    fresh = {r.id: (r.verdict, r.checked, r.violations, r.errors) for r in audit(random=200, seed=1)}
    assert documented == fresh
