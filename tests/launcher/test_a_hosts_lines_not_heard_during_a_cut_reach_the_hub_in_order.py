"""The lines of a host's run that the hub did not hear live (a network cut drops them: zenoh has
no route) reach it afterwards, from the lines the host's agent keeps, in their order and marked
late; lines the agent no longer keeps are counted. Here the two sides' bookkeeping
(iotad/launcher/hosts/agent_lines.py) is driven as the agent and the hub's fleet drive it, with the
cut being lines that never arrive; tests/hosts has the same over a real cut."""
from iotad.launcher.hosts.agent_lines import HeardLines, KeptLines


def agent_run(lines: list[str], kept: int = 100, run: int = 4242) -> tuple[KeptLines, list[dict]]:
    """An agent's run printing `lines`: what it keeps, and what it publishes live."""
    agent = KeptLines(kept)
    agent.start(run)
    return agent, [{"line": text, "n": agent.add(text), "run": run} for text in lines]


def hub_hears(heard: HeardLines, agent: KeptLines, published: list[dict], lost: set[int]) -> list[str]:
    """The hub's fleet: every live line but those numbered in `lost`, asking the agent whenever
    one comes past a gap; what it prints, as the fleet prints it."""
    printed: list[str] = []

    def show(lines):
        printed.extend(f"(late) {text}" if late else text for text, late in lines)

    for payload in published:
        if payload["n"] in lost:
            continue
        lines, ask = heard.live(payload["run"], payload["n"], payload["line"])
        show(lines)
        while ask:
            lines, dropped, ask = heard.answered(agent.after(heard.after(), limit=3))
            if dropped:
                printed.append(f"({dropped} lost)")
            show(lines)
    return printed


def test_lines_missed_in_a_cut_are_printed_late_before_the_line_that_revealed_them():
    agent, published = agent_run([f"line {k}" for k in range(1, 11)])
    printed = hub_hears(HeardLines(), agent, published, lost={4, 5, 6})
    assert printed == ["line 1", "line 2", "line 3", "(late) line 4", "(late) line 5", "(late) line 6",
                       "line 7", "line 8", "line 9", "line 10"]


def test_a_gap_longer_than_one_answer_is_asked_for_again_until_it_is_filled():
    agent, published = agent_run([f"line {k}" for k in range(1, 21)])
    printed = hub_hears(HeardLines(), agent, published, lost=set(range(2, 17)))  # 15 lines, 3 an answer
    assert printed == ["line 1"] + [f"(late) line {k}" for k in range(2, 17)] + [f"line {k}" for k in range(17, 21)]


def test_lines_the_agent_no_longer_keeps_are_counted_not_lost_silently():
    agent, published = agent_run([f"line {k}" for k in range(1, 11)], kept=4)
    # the hub hears 1 and 2, then nothing until 10: the agent keeps only 7-10
    printed = hub_hears(HeardLines(), agent, published, lost=set(range(3, 10)))
    assert printed == ["line 1", "line 2", "(4 lost)", "(late) line 7", "(late) line 8", "(late) line 9", "line 10"]


def test_the_last_lines_of_a_run_not_heard_are_asked_for_when_its_exit_counts_them():
    agent, published = agent_run(["a", "b", "c", "d"])
    heard = HeardLines()
    assert hub_hears(heard, agent, published, lost={3, 4}) == ["a", "b"]
    assert heard.want_tail(4242, 4)  # the exit: {"lines": 4}
    lines, dropped, again = heard.answered(agent.after(heard.after()))
    assert (lines, dropped, again) == ([("c", True), ("d", True)], 0, False)
    assert not heard.want_tail(4242, 4)  # all four printed: nothing to ask


def test_an_agent_that_does_not_answer_leaves_the_held_lines_printed_and_the_gap_counted():
    agent, published = agent_run(["a", "b", "c", "d", "e"])
    heard = HeardLines()
    heard.live(4242, 1, "a")
    assert heard.live(4242, 4, "d") == ([], True)   # 2 and 3 not heard: ask
    assert heard.live(4242, 5, "e") == ([], False)  # held while the question is out
    assert heard.unanswered() == ([("d", False), ("e", False)], 2)
    assert heard.live(4242, 6, "f") == ([("f", False)], False)


def test_a_new_run_of_the_host_numbers_its_lines_from_one_again():
    heard = HeardLines()
    assert heard.live(1, 1, "first run")[0] == [("first run", False)]
    assert heard.live(1, 2, "its second line")[0] == [("its second line", False)]
    # the host's part given again (a new launcher): its line 1 is printed, not taken as seen
    assert heard.live(2, 1, "second run") == ([("second run", False)], False)
    # an answer about the other run is not printed as this one's
    heard.live(2, 3, "held")
    assert heard.answered({"run": 1, "first": 1, "count": 2, "lines": [[2, "its second line"]]}) == \
        ([("held", False)], 0, False)


def test_lines_from_an_agent_without_numbers_are_printed_as_they_come():
    heard = HeardLines()
    assert heard.live(None, None, "old agent") == ([("old agent", False)], False)


def test_a_malformed_answer_prints_nothing_of_it():
    heard = HeardLines()
    heard.live(7, 1, "a")
    heard.live(7, 3, "c")
    lines, dropped, again = heard.answered({"run": 7, "first": "x", "lines": [["2", 5], [2, None], "junk"]})
    # nothing usable for line 2: the held line is printed and the gap counted as not heard
    assert (lines, dropped, again) == ([("c", False)], 1, False)
