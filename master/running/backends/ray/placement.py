"""Which node each Ray worker of a run starts on (docs/distributed.md, "Placement").

Ray's ``SPREAD`` strategy is a preference, not a promise: with workers that take no CPU
(``num_cpus=0``, as dsim's do) it put both workers of a two-node run on one node in 4
of 9 tries.  So dsim chooses the node of every worker itself, before any starts, and
pins it there with Ray's node-affinity scheduling (``soft=False``: that node or none).
A placement group with the ``STRICT_SPREAD`` strategy would promise the same, but its
bundles must reserve resources (dsim's workers reserve none, so that any number share a
node) and a bundle cannot move to another node when a worker is started again after
its node is lost (recovery.py picks that node by the same rule, the least loaded).

The rule: the workers of placed components first, each on the node holding its Ray
resource that has the fewest of this run's workers so far; then the workers of the
components without a placement, each on the node with the fewest (a node of its own
while there is one), among the nodes with CPUs (a head started with ``--num-cpus=0``
is kept free of them); ties go to the node with more CPUs.  When the cluster has
fewer such nodes than those workers, one note says so and which components share a
node: the run still goes on, as evenly spread as the nodes allow.
"""
from __future__ import annotations

import socket

#: components a placement note names, at most
NAMED = 5


class Placement:
    """The node of every worker of a run: :meth:`node` for the next worker of a
    group (its Ray resource, '' for none), :attr:`notes` what did not hold."""

    def __init__(self, connection, groups: list[tuple[str, int]]):
        """``groups``: (placement resource or '', number of workers) in start order."""
        nodes = [n for n in connection.ray.nodes() if n.get("Alive") and _answers(n)]
        self.nodes = {n["NodeID"]: n for n in nodes}
        self.load = {n["NodeID"]: 0 for n in nodes}
        self.notes: list[str] = []
        self._chosen: dict[str, list[str]] = {}
        # placed workers first: where they go is not a choice, and the others avoid them
        for resource, count in sorted(groups, key=lambda group: not group[0]):
            self._chosen[resource] = [self._pick(resource) for _ in range(count)]
        self._spread_nodes = len(self._candidates(""))
        self._cluster = len(nodes) > 1 or bool(getattr(connection, "address", None))

    def _candidates(self, resource: str) -> list[str]:
        if resource:
            return [i for i, n in self.nodes.items() if n.get("Resources", {}).get(resource)]
        working = [i for i, n in self.nodes.items() if n.get("Resources", {}).get("CPU")]
        return working or list(self.nodes)

    def _pick(self, resource: str) -> str | None:
        candidates = self._candidates(resource)
        if not candidates:  # Ray's nodes said otherwise a moment ago: let Ray choose
            return None
        chosen = min(candidates, key=lambda i: (self.load[i], -self._cpus(i)))
        self.load[chosen] += 1
        return chosen

    def _cpus(self, node: str) -> float:
        return self.nodes[node].get("Resources", {}).get("CPU", 0.0)

    def options(self, resource: str, number: int) -> dict:
        """The Ray options of worker ``number`` of the group placed on ``resource``."""
        chosen = self._chosen.get(resource, [])
        node = chosen[number] if number < len(chosen) else None
        if node is None:
            return {} if resource else {"scheduling_strategy": "SPREAD"}
        # here, not at the top: Ray is an optional extra (see ray_cluster.ray_module)
        from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

        return {"scheduling_strategy": NodeAffinitySchedulingStrategy(node_id=node,
                                                                      soft=False)}

    def check(self, owners: dict[int, list[str]]) -> None:
        """Note why the workers of the components without a placement do not each have a
        node of their own, if they do not (``owners``: that group's worker number ->
        its components).  Silent on a one-node Ray of this machine: nothing to spread."""
        chosen = self._chosen.get("", [])
        if len(chosen) <= self._spread_nodes or not self._cluster:
            return
        shared = {}
        for number, node in enumerate(chosen):
            shared.setdefault(node, []).extend(owners.get(number, []))
        node, names = max(shared.items(), key=lambda item: len(item[1]))
        where = self.nodes.get(node, {}).get("NodeManagerAddress", "?")
        quoted = ", ".join(f"'{name}'" for name in names[:NAMED])
        if len(names) > NAMED:  # one line, also for a chain of ten thousand
            quoted += f" and {len(names) - NAMED} more"
        self.notes.append(
            f"placement: {len(chosen)} workers of components without a placement, "
            f"{self._spread_nodes} node{'s' * (self._spread_nodes != 1)} with CPUs in the "
            f"cluster: not one node each (components {quoted} "
            f"share node {where}, {str(node)[:12]})")


def _answers(node: dict) -> bool:
    """Whether a node's raylet accepts a connection (within a second): the cluster
    learns of a lost node only after its health checks, many seconds later."""
    try:
        with socket.create_connection((node["NodeManagerAddress"], node["NodeManagerPort"]),
                                      timeout=1.0):
            return True
    except (OSError, KeyError):
        return False
