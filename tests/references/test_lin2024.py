"""The published numbers of Lin et al. 2024 in starsense.references.lin2024, against the paper.

The paper's plain-text copy (shared/papers/002_*.txt) is the authority: every cell of Tables 1,
3 and 4 must equal the module's value exactly (both are the printed decimals).
"""

from __future__ import annotations

import re

import pytest

from starsense.references import lin2024

PAPER = "002_e503e659d5511419.txt"


@pytest.fixture(scope="module")
def paper_rows(shared_dir):
    path = shared_dir / "papers" / PAPER
    if not path.is_file():
        pytest.skip(f"{path} not found")
    rows = {}
    for line in path.read_text(encoding="utf-8").splitlines():
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 6 and "easurement error" in cells[0]:
            rows.setdefault(cells[0], []).append([float(c) for c in cells[1:]])
    return rows


def _sigma(label: str) -> float:
    return float(re.search(r"error \$?(\d+\.\d+)", label).group(1))


def test_lin2024_table1(paper_rows):
    table1 = [(k, v[0]) for k, v in paper_rows.items() if k.startswith("Measurement error")]
    assert tuple(_sigma(k) for k, _ in table1) == lin2024.TABLE1_SIGMAS_ARCSEC
    for i, (_, cells) in enumerate(table1):
        ours = [lin2024.TABLE1_PERCENT[c][i] for c in lin2024.CONFIGURATION_ORDER]
        assert cells == ours


def test_lin2024_tables_3_and_4(paper_rows):
    for j, key in enumerate(("table3", "table4")):
        acc = lin2024.FIELD_TABLES[key]["accuracy_arcsec"]
        for sigma in lin2024.TABLE3_4_SIGMAS_ARCSEC:
            cells = paper_rows[f'Average measurement error {sigma}"'][j]
            assert cells == [acc[sigma][c] for c in lin2024.CONFIGURATION_ORDER]
    assert lin2024.FIELD_TABLES["table3"]["center_deg"] == (150.0, 0.0)
    assert lin2024.FIELD_TABLES["table4"]["center_deg"] == (240.0, -80.0)


def test_lin2024_camera():
    # Table 2: 2048 effective pixels of 2 arcsec for the science field, 1.6 deg lens circle
    assert lin2024.CAMERA_FOV_DEG == pytest.approx(2048 * 2 / 3600)
    assert lin2024.PATTERN_FOVS_DEG[0] == pytest.approx(2 * 2896 / 3600, abs=0.01)
