"""The tool server's link counters: no increment is lost between threads."""

from __future__ import annotations

import threading

import pytest

from articutool.link.counters import LinkCounters


def test_increments_from_many_threads_are_all_counted() -> None:
    c = LinkCounters()
    per, threads = 20_000, 4

    def work() -> None:
        for _ in range(per):
            c.bump("decode_errors")
            c.bump("ticks", 2)

    ts = [threading.Thread(target=work) for _ in range(threads)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    snap = c.snapshot()
    assert snap["decode_errors"] == c["decode_errors"] == per * threads
    assert snap["ticks"] == 2 * per * threads
    assert set(snap) >= {"link_losses", "refused_unpaired", "commands"}
    assert not any(k.startswith("_") for k in snap)


@pytest.mark.parametrize("name", ["nonsense", "_lock", "bump"])
def test_an_unknown_counter_is_a_key_error(name: str) -> None:
    c = LinkCounters()
    with pytest.raises(KeyError):
        c.bump(name)
    with pytest.raises(KeyError):
        c[name]
