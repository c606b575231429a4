"""The stratified sample of `make mutate`: every product file gets its share of MUTANTS counted
mutants (compiled and not reviewed as equivalent), so that a score carries over to the whole
firmware and to each component.

- Shares: each file's weight is its number of mutated lines; every file with a mutant gets at
  least one when MUTANTS is at least the number of files, the rest goes by largest remainder.
- Within a file, the candidates are in a seeded order that draws the rule family first
  (universalmutator's rules weigh UNIVERSAL_WEIGHT, each realistic operator 1), then a mutant
  of it: the realistic operators are not drowned by the many regexp rules.
- A file's candidates are taken in that order until its share is counted: a mutant that does
  not compile, or is listed as equivalent, is replaced by the file's next one. MUTANTS counts
  mutants, not draws.
- A shard K/N takes every N-th candidate of each file (from the K-th) and its part of each
  file's share (the remainders rotate over the shards), so the shards of one sample add up to
  MUTANTS counted mutants with no coordination between them.
"""

from __future__ import annotations

import random
from collections import Counter, defaultdict, deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass

from mutate_mutants import Mutant
from mutate_operators import RULES as REALISTIC_RULES

UNIVERSAL_WEIGHT = 3


@dataclass(frozen=True)
class Plan:
    """Per file: how many counted mutants it must give, and its candidates in order."""

    targets: dict[str, int]
    candidates: dict[str, list[Mutant]]

    @property
    def count(self) -> int:
        return sum(self.targets.values())


def family(rule: str) -> str:
    return rule if rule in REALISTIC_RULES else "universalmutator"


def shares(weights: dict[str, int], count: int) -> dict[str, int]:
    """`count` split over the files in proportion to their weights (largest remainder), at
    least one each when there are enough; a file never gets more than its weight."""
    files = sorted(f for f, w in weights.items() if w > 0)
    if not files or count <= 0:
        return {}
    result = dict.fromkeys(files, 0)
    if count >= len(files):
        result = dict.fromkeys(files, 1)
    left = count - sum(result.values())
    total = sum(weights[f] for f in files)
    exact = {f: left * weights[f] / total for f in files}
    for f in files:
        result[f] += int(exact[f])
    remainder = count - sum(result.values())
    for f in sorted(files, key=lambda f: (-(exact[f] - int(exact[f])), f))[:remainder]:
        result[f] += 1
    return {f: min(n, weights[f]) for f, n in result.items() if n}


def file_order(mutants: Sequence[Mutant], rng: random.Random) -> list[Mutant]:
    """One file's mutants in the seeded order: a rule family drawn by weight, then one of it."""
    groups: dict[str, list[Mutant]] = defaultdict(list)
    for mutant in sorted(mutants, key=lambda m: m.id):
        groups[family(mutant.rule)].append(mutant)
    for name in sorted(groups):
        rng.shuffle(groups[name])
    order = []
    while groups:
        names = sorted(groups)
        weights = [UNIVERSAL_WEIGHT if n == "universalmutator" else 1 for n in names]
        name = rng.choices(names, weights)[0]
        order.append(groups[name].pop())
        if not groups[name]:
            del groups[name]
    return order


def plan(mutants: Sequence[Mutant], count: int, seed: int, shard: tuple[int, int] | None = None) -> Plan:
    """The sample of `count` counted mutants (or shard (K, N) of it)."""
    by_file: dict[str, list[Mutant]] = defaultdict(list)
    for mutant in mutants:
        by_file[mutant.path].append(mutant)
    weights = {path: len({m.line for m in group}) for path, group in by_file.items()}
    targets = shares(weights, count)
    candidates = {}
    for path in sorted(targets):
        order = file_order(by_file[path], random.Random(f"{seed}:{path}"))
        candidates[path] = order
    if shard is not None:
        index, total = shard
        split = {}
        for rank, path in enumerate(sorted(targets)):
            base, extra = divmod(targets[path], total)
            split[path] = base + (1 if (rank + index - 1) % total < extra else 0)
        targets = {p: n for p, n in split.items() if n}
        candidates = {p: candidates[p][index - 1 :: total] for p in targets}
    return Plan(targets, {p: candidates[p] for p in targets})


def take(plan: Plan, counts: Callable[[Mutant], bool]) -> Iterator[Mutant]:
    """The plan's candidates in turn over the files (one each, round after round), each file's
    until `counts` said yes to its share of them; yields each candidate before asking."""
    queues = {path: deque(plan.candidates[path]) for path in sorted(plan.targets)}
    got: Counter[str] = Counter()
    progressed = True
    while progressed:
        progressed = False
        for path, queue in queues.items():
            if got[path] >= plan.targets[path] or not queue:
                continue
            mutant = queue.popleft()
            progressed = True
            yield mutant
            if counts(mutant):
                got[path] += 1


def first_choices(plan: Plan) -> list[Mutant]:
    """What the plan takes if every candidate counts (`list` shows it; nothing built)."""
    return list(take(plan, lambda _: True))
