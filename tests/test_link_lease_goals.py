"""The command lease and the goal table on their own (``link/lease.py``, ``link/goals.py``):
pure state driven with explicit times, as the server drives them."""

import json

from hypothesis import given
from hypothesis import strategies as st

from articutool.link import messages as m
from articutool.link.goals import Goal, GoalTable
from articutool.link.lease import CommandLease
from articutool.tool.api import PrimitiveStatus

TIMEOUT = 2.0


def test_first_commander_holds_others_are_refused_naming_it_and_stops_pass() -> None:
    lease = CommandLease(TIMEOUT, "tool-1", None)
    assert lease.acquire("pc-a", 0.0) == ""
    refusal = lease.acquire("pc-b", 1.0)
    assert refusal.startswith("refused: pc-a holds the command lease")
    assert lease.acquire("pc-b", 1.0, stop=True) == ""  # a stop, and the lease stays
    assert lease.holder == "pc-a"


def test_heartbeats_renew_and_silence_expires_the_lease() -> None:
    lease = CommandLease(TIMEOUT, "tool-1", None)
    lease.acquire("pc-a", 0.0)
    lease.renew("pc-b", 1.5)  # not the holder: no effect
    lease.renew("pc-a", 1.5)
    assert lease.acquire("pc-b", 3.0) != ""  # pc-a heard 1.5 s ago
    assert lease.acquire("pc-b", 3.6) == ""  # silent 2.1 s > timeout: pc-b takes it
    assert lease.holder == "pc-b"
    assert [json.loads(a)["event"] for a in lease.audit] == [
        "lease_granted", "lease_expired", "lease_granted"]


def test_take_over_and_release_are_audited_to_the_file(tmp_path) -> None:
    log = tmp_path / "audit.jsonl"
    lease = CommandLease(TIMEOUT, "tool-1", str(log))
    lease.acquire("pc-a", 0.0)
    assert lease.take_over("pc-b", 0.5) == "pc-a"
    lease.record("take_over", "pc-b", "pc-a")
    assert not lease.release("pc-a")
    assert lease.release("pc-b") and lease.holder is None
    recs = [json.loads(line) for line in log.read_text().splitlines()]
    assert [(r["event"], r["client"], r["previous_holder"], r["tool_id"]) for r in recs] == [
        ("lease_granted", "pc-a", None, "tool-1"), ("take_over", "pc-b", "pc-a", "tool-1")]


def _status(done: bool, success: bool = False) -> PrimitiveStatus:
    return PrimitiveStatus("TWIRL", 100.0 if done else 50.0, "", (0.1, 0.2), done, success,
                           "ok" if success else "failed", (0.3, 0.4) if done else ())


def test_settle_reports_progress_then_the_result_and_its_waiters_once() -> None:
    table = GoalTable()
    assert table.settle(lambda: _status(True)) is None  # nothing runs: status not read
    goal = Goal(b"a" * 16, "TWIRL", 0.0, m.GoalStatus.EXECUTING)
    table.remember(goal)
    table.active = goal
    goal.waiters.append("waiter")  # type: ignore[arg-type]
    assert isinstance(table.settle(lambda: _status(False)), PrimitiveStatus)
    goal.cancel_requested = True
    waiters, result = table.settle(lambda: _status(True))  # type: ignore[misc]
    assert waiters == ["waiter"] and table.active is None
    assert result.status == m.GoalStatus.CANCELED and result.final_joint_values == (0.3, 0.4)
    assert table.statuses() == [(b"a" * 16, 0.0, m.GoalStatus.CANCELED)]


@given(st.lists(st.booleans(), min_size=1, max_size=60))
def test_the_table_forgets_only_the_oldest_finished_goals(finished: list[bool]) -> None:
    table = GoalTable(keep=8)
    for i, done in enumerate(finished):
        result = m.PrimitiveResult(True, "", (), m.GoalStatus.SUCCEEDED) if done else None
        table.remember(Goal(i.to_bytes(16, "big"), "TWIRL", float(i), 0, result=result))
    kept = [int.from_bytes(g, "big") for g, _, _ in table.statuses()]
    running = [i for i, done in enumerate(finished) if not done]
    assert set(running) <= set(kept)  # a running goal is never forgotten
    assert len(kept) == max(len(running), min(len(finished), 8))
    dropped = sorted(set(range(len(finished))) - set(kept))
    assert all(finished[i] for i in dropped)
    kept_done = [i for i in kept if finished[i]]
    if dropped and kept_done:  # the ones forgotten are older than every finished goal kept
        assert max(dropped) < min(kept_done)
