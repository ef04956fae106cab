"""Progress off a terminal (plain lines every few seconds), on one (tqdm), and none when
quiet; and the one format of counts and rates in messages (sweep._format)."""
import io

import pytest

from sweep import _format, cli
from sweep.sweeps import config, limits, progress, runner

CONFIG = """
[design]
kind = "grid"
alpha = 1.5
beta = 1.5
gamma = {start = 0.0, stop = 0.2, num = 10}
gtilde = [0.0, 1.0, 10.0]
[outputs]
e = ["ord1"]
[run]
chunk_size = 7
"""


class FakeClock:
    def __init__(self):
        self.now = 100.0

    def __call__(self):
        return self.now


def test_plain_lines_every_interval_with_rate_and_eta():
    clock, out = FakeClock(), io.StringIO()
    with progress.progress(1_000_000, desc="doe.nc", interval=10.0, stream=out,
                           clock=clock) as bar:
        assert isinstance(bar, progress.LineProgress)
        for _ in range(4):            # 4 updates of 100,000 points, 4 s apart
            clock.now += 4.0
            bar.update(100_000)
        clock.now += 4.0
        bar.update(600_000)
    lines = out.getvalue().splitlines()
    assert lines == [
        "doe.nc: 300,000/1,000,000 points (30%) in 12 s, 25,000 points/s, ETA 28 s",
        "doe.nc: 1,000,000/1,000,000 points (100%) in 20 s, 50,000 points/s",
    ]


def test_resumed_points_count_as_done_but_not_in_the_rate():
    clock, out = FakeClock(), io.StringIO()
    bar = progress.progress(100, 60, interval=0.0, stream=out, clock=clock)
    clock.now += 2.0
    bar.update(10)
    assert out.getvalue() == "70/100 points (70%) in 2 s, 5 points/s, ETA 6 s\n"


def test_nothing_when_quiet_and_no_final_line_after_an_error():
    out = io.StringIO()
    with progress.progress(10, quiet=True, stream=out) as bar:
        bar.update(10)
    with pytest.raises(KeyboardInterrupt):
        with progress.progress(10, interval=99.0, stream=out) as bar:
            bar.update(5)
            raise KeyboardInterrupt
    assert out.getvalue() == ""


def test_a_terminal_gets_the_tqdm_bar():
    class Tty(io.StringIO):
        def isatty(self):
            return True

    out = Tty()
    with progress.progress(50, desc="x.nc", stream=out) as bar:
        bar.update(50)
    from tqdm import tqdm

    assert isinstance(bar, tqdm) and "100%|" in out.getvalue() and "pt/s]" in out.getvalue()


def test_runner_prints_lines_off_a_terminal(tmp_path, capsys):
    cfg = config.loads(CONFIG, source="p.toml")
    runner.run(cfg, tmp_path / "p.nc", progress_interval=0.0)
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("p.nc: ")]
    assert len(lines) == 5 + 1               # one per chunk (interval 0), one at the end
    assert lines[-1].startswith("p.nc: 30/30 points (100%) in ")
    assert "points/s, ETA" in lines[0] and lines[-1].endswith(" points/s")
    assert "sweep: grid design alpha[1] x beta[1] x gamma[10] x gtilde[3] = 30 points; " \
           "5 chunks of <= 7 points;" in err
    runner.run(cfg, tmp_path / "q.nc", quiet=True, progress_interval=0.0)
    assert capsys.readouterr().err == ""


def test_cli_progress_interval(tmp_path, capsys):
    path = tmp_path / "c.toml"
    path.write_text(CONFIG.replace("chunk_size = 7", "chunk_size = 30"))
    assert cli.main(["run", str(path), "-o", str(tmp_path / "c.nc"),
                     "--progress-interval", "1e-9"]) == 0
    err = capsys.readouterr().err
    assert "c.nc: 30/30 points (100%)" in err and "1 chunk of <= 30 points" in err
    assert limits.PROGRESS_INTERVAL_S == 10.0


def test_one_format_for_counts_and_rates():
    assert _format.count(1, "chunk") == "1 chunk"
    assert _format.count(2, "chunk") == "2 chunks"
    assert _format.count(120_701, "point") == "120,701 points"
    assert _format.rate(12_345.4) == "12,345 points/s"
    assert _format.rate(12.345) == "12.3 points/s"
    assert _format.rate(float("nan")) == "n/a points/s"
    assert _format.format_duration(4000) == "1 h 6 min"
