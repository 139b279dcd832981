"""The ``articutool meal`` progress display: a py_trees visitor that redraws the tree.

On a terminal it shows the ticked part of the bite tree live, with each behaviour's status
(py_trees' :func:`~py_trees.display.unicode_tree` from a
:class:`~py_trees.visitors.SnapshotVisitor`'s snapshot); elsewhere it prints one line each
time the running behaviour changes, with the simulated time and the planning attempts.
"""

from __future__ import annotations

from typing import Any

import py_trees
from rich.console import Console
from rich.markup import escape
from rich.text import Text

from articutool.feeding.behaviours import BiteStage, CountedRetry

__all__ = ["TreeProgress"]


class TreeProgress(py_trees.visitors.SnapshotVisitor):
    """Add to a :class:`~py_trees.trees.BehaviourTree`'s visitors; call :meth:`stop` at the
    end. ``world`` gives the simulated time; ``live`` asks for the live tree (used only when
    stderr is a terminal)."""

    def __init__(self, world: Any, live: bool) -> None:
        super().__init__()
        self.world, self.root, self.last = world, None, ""
        self.console = Console(stderr=True, soft_wrap=True)  # log lines are not wrapped
        self.live = None
        if live and self.console.is_terminal:
            from rich.live import Live

            self.live = Live(console=self.console, refresh_per_second=4, transient=True)
            self.live.start()

    def run(self, behaviour: py_trees.behaviour.Behaviour) -> None:
        """Record the behaviour's status (and the root: the one visited node without a
        parent)."""
        super().run(behaviour)
        if behaviour.parent is None:
            self.root = behaviour

    def finalise(self) -> None:
        """After each tick: redraw the tree, or print a line if the running behaviour
        changed."""
        if self.root is None:
            return
        if self.live is not None:
            # py_trees' text holds ANSI colours and "[o]"/"[-]" symbols, which are not markup.
            self.live.update(Text.from_ansi(py_trees.display.unicode_tree(
                self.root, show_status=True, show_only_visited=True, visited=self.visited,
                previously_visited=self.previously_visited)))
            return
        tip = self.root.tip()
        path = _ancestry(tip)
        where = " › ".join(n.name for n in path if isinstance(n, BiteStage) or n is tip)
        attempts = "".join(f" (attempt {n.count})" for n in path if isinstance(n, CountedRetry)
                           and n.key.startswith("planning_attempts_"))
        line = f"{where}{attempts}"
        if line != self.last:
            feedback = tip.feedback_message if tip is not None else ""
            self.console.print(f"[dim]{self.world.time:7.1f} s[/dim] {escape(line)}"
                               + (f" [dim]– {escape(feedback)}[/dim]" if feedback else ""),
                               highlight=False)
            self.last = line

    def stop(self) -> None:
        """End the live display (it leaves no trace on the terminal)."""
        if self.live is not None:
            self.live.stop()


def _ancestry(node: Any) -> list[Any]:
    """``node`` and its parents, root first (empty for ``None``)."""
    path = []
    while node is not None:
        path.append(node)
        node = node.parent
    return path[::-1]
