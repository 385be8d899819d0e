"""benchmarks/held_out_table.py: the validation table of a held-out run, from its JSON lines."""

from __future__ import annotations

import json

import pytest

from benchmarks.held_out_table import interval, load, main, table


def _case(i, hidden, final, answer, wall, **kw):
    return {"case": i, "hidden": hidden, "final": final, "hit": answer == "hit", "answer": answer,
            "baseline_error": 10.0, "final_error": 3.0, "truth_error": 2.5, "wall_s": wall, **kw}


def test_the_interval_is_clopper_pearson():
    lo, hi = interval(4, 4)
    assert lo == pytest.approx(0.025 ** 0.25, abs=1e-9) and hi == 1.0  # (alpha / 2)^(1/n)
    lo, hi = interval(0, 6)
    assert lo == 0.0 and hi == pytest.approx(1.0 - 0.025 ** (1 / 6), abs=1e-9)


def test_the_page_counts_hits_undecided_and_wrong_apart(tmp_path):
    lines = [_case(0, [], [], "hit", 30.0), _case(1, ["a", "b"], ["a"], "wrong", 300.0),
             _case(2, ["c"], [], "indistinguishable", 100.0, undecided_between=["c", "d"],
                   truth_among_undecided=True),
             _case(3, ["a", "b"], ["b", "a"], "hit", 200.0)]
    path = tmp_path / "r.jsonl"
    path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    page = table(load([str(path)]), "Seed 9")
    assert page.startswith("# Seed 9")
    assert "**Hits: 2 of 4** (50 %" in page.replace("50%", "50 %")
    assert "Indistinguishable (the data could not decide; counted apart): 1, of which the hidden " \
           "set was among the contenders in 1. Wrong names: 1." in page
    assert "controls 1/1; one effect 0/1; two effects 1/2" in page
    assert "median 150 s, worst 300 s" in page
    assert "| 2 | c | - | indistinguishable (c / d) |" in page
    out = tmp_path / "t.md"
    assert main([str(path), "--title", "Seed 9", "--out", str(out)]) == 0
    assert out.read_text() == page


def test_a_case_run_again_keeps_its_last_line(tmp_path):
    a, b = tmp_path / "a.jsonl", tmp_path / "b.jsonl"
    a.write_text(json.dumps(_case(0, [], ["x"], "wrong", 10.0)) + "\n")
    b.write_text(json.dumps(_case(0, [], [], "hit", 12.0)) + "\n")
    (case,) = load([str(a), str(b)])
    assert case["answer"] == "hit"


def test_a_case_stopped_at_the_time_limit_is_a_miss_counted_apart(tmp_path):
    lines = [_case(0, [], [], "hit", 30.0),
             _case(1, ["a"], [], "time limit", 1800.0, baseline_error=float("nan"),
                   final_error=float("nan")),
             _case(2, ["a"], ["b"], "wrong", 100.0)]
    path = tmp_path / "r.jsonl"
    path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    page = table(load([str(path)]), "Seed 9")
    assert "**Hits: 1 of 3**" in page
    assert "Wrong names: 1. Stopped at the case time limit (no answer, a miss): 1." in page
    assert "worst at least 1800 s" in page
    assert "| 1 | a | - | time limit | - | - | 2.5 | 1800 |" in page


def test_the_page_gives_the_run_s_peak_memory_where_recorded(tmp_path):
    lines = [_case(0, [], [], "hit", 30.0, peak_rss_mb={"parent": 310.0, "largest_worker": 250.4}),
             _case(1, ["a"], ["a"], "hit", 60.0,
                   peak_rss_mb={"parent": 420.2, "largest_worker": 380.0}),
             _case(2, ["b"], ["b"], "hit", 60.0)]  # a line from before memory was recorded
    path = tmp_path / "r.jsonl"
    path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    page = table(load([str(path)]), "Seed 9")
    assert ("- Peak resident memory over the run: 420 MB (the diagnosing process), 380 MB (its "
            "largest worker process).") in page
    older = tmp_path / "o.jsonl"
    older.write_text(json.dumps(lines[2]) + "\n")
    assert "Peak resident memory" not in table(load([str(older)]), "Seed 9")


def test_a_case_ended_by_the_run_s_own_limit_is_an_answer_and_is_marked(tmp_path):
    lines = [_case(0, ["a"], ["a"], "hit", 540.0, run_time_limited="ended forward step 2"),
             _case(1, [], [], "hit", 60.0, run_time_limited="")]
    path = tmp_path / "r.jsonl"
    path.write_text("".join(json.dumps(x) + "\n" for x in lines))
    page = table(load([str(path)]), "Seed 9")
    assert "**Hits: 2 of 2**" in page
    assert "Ended by the run's own time limit (`--max-time`; the model it had is the answer, " \
           "judged like any other): 1." in page
    assert "| 0 | a | a | hit (run time limit) |" in page
    assert "| 1 | - | - | hit |" in page
