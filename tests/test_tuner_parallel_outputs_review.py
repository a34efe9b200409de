"""Review of the tuner's figures drawn while the falsification search runs on worker processes:
a figure that fails, or an interrupt during the phase, leaves the output folder as the serial
order did (the tuned system written before the figures; no search files after an interrupt)."""

from __future__ import annotations

import pytest

from hybridnav.cli import main
import hybridnav.tuner.run as run

from tests.test_tuner import SMALL


def _job(tmp_path):
    p = tmp_path / "job.toml"
    p.write_text(SMALL)
    return p


def test_a_failing_figure_still_leaves_the_tuned_system_written(tmp_path, monkeypatch):
    def boom(*a, **k):
        raise RuntimeError("figure boom")

    monkeypatch.setattr(run, "_convergence", boom)
    out = tmp_path / "out"
    with pytest.raises(RuntimeError, match="figure boom"):
        main(["tune", str(_job(tmp_path)), "--out", str(out), "--workers", "2"])
    # the search's files and then result.save's, as with one process (and before the figures
    # were drawn meanwhile): only the figures are missing
    for name in ("falsification.csv", "result.json", "fis.json", "logbook.csv"):
        assert (out / name).exists(), name


def test_an_interrupt_while_drawing_writes_no_search_files_afterwards(tmp_path, monkeypatch,
                                                                       capsys):
    def interrupt(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(run, "_convergence", interrupt)
    out = tmp_path / "out"
    assert main(["tune", str(_job(tmp_path)), "--out", str(out), "--workers", "2"]) == 130
    assert "hybridnav: interrupted" in capsys.readouterr().err
    assert not (out / "falsification.csv").exists()
    assert not (out / "falsified").exists()
