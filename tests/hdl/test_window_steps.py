# amaranth: UnusedElaboratable=no
"""The window core's step issue and beat metadata, each alone against a Python model at the latency its
docstring states (:mod:`lost.hdl.window_steps`)."""

import numpy as np
import pytest

from lost.hdl.interface import CorrelatorParameters
from lost.hdl.window_steps import BeatMetadata, StepIssue
from lost.model.cycles_window import completing_steps, window_timing

from .test_blocks import simulate

# --- The step issue -------------------------------------------------------------------------------------


def step_sequence(words, flush_steps):
    """A run's steps in order: ``(is_word, address)``, the map words first, then the flush steps."""
    return [(True, a) for a in range(words)] + [(False, None)] * flush_steps


class IssueModel:
    """What the step issue should do: the next step of the run goes out whenever it can.

    A step can go out with a credit and, for a map word, the sequencer ready. ``clear`` returns the
    run to its first step, ``begin`` sets it going (both on the edge they are sampled on, after that
    edge's issue).
    """

    def __init__(self, words, flush_steps):
        self.sequence = step_sequence(words, flush_steps)
        self.running, self.position = False, 0

    @property
    def next_step(self):
        return self.sequence[self.position] if self.running else None

    def issues(self, credit, ready):
        step = self.next_step
        return step is not None and credit and (ready or not step[0])

    def edge(self, credit, ready, clear, begin):
        if self.issues(credit, ready):
            self.position += 1
            self.running = self.position < len(self.sequence)
        if clear:
            self.position = 0
        if begin:
            self.running = True


@pytest.mark.parametrize("map_shape, patch_shape, lanes, credit_rate, ready_rate", [
    ((5, 7), (3, 4), 1, 0.6, 0.7), ((4, 8), (2, 5), 3, 0.5, 0.5), ((3, 4), (2, 2), 2, 0.9, 0.3),
])
def test_step_issue_issues_each_step_once_against_a_credit(map_shape, patch_shape, lanes, credit_rate, ready_rate):
    timing = window_timing(map_shape, patch_shape, lanes)
    words = map_shape[0] * timing.groups
    dut = StepIssue(words=words, flush_steps=timing.flush_steps)
    model = IssueModel(words, timing.flush_steps)
    rng = np.random.default_rng([words, lanes])
    runs = []  # per begin: the requests that transferred, and the steps taken (step_is_word on each advance)
    restarted = []

    async def bench(ctx):
        previous_issue = previous_word = False
        previous_run = None  # the run of the step issued in the last cycle
        idle_for, cycle = 0, 0
        while len(runs) < 4 or model.running or previous_issue:
            credit, ready = bool(rng.random() < credit_rate), bool(rng.random() < ready_rate)
            # A clear while idle, a begin after it; in the second run, a clear with a begin mid-run.
            clear = not model.running and idle_for in (2, 3)
            begin = not model.running and idle_for == 4
            if len(runs) == 2 and model.running and model.position >= words // 2 and not restarted:
                clear = begin = True
                restarted.append(cycle)
            ctx.set(dut.has_credit, credit)
            ctx.set(dut.request.ready, ready)
            ctx.set(dut.clear, clear)
            ctx.set(dut.begin, begin)

            issue = model.issues(credit, ready)
            step = model.next_step
            assert ctx.get(dut.issue) == issue, cycle
            assert ctx.get(dut.request.valid) == (step is not None and step[0] and credit), cycle
            if step is not None and step[0]:
                assert ctx.get(dut.request.payload) == step[1], cycle
            # Taken on the edge after the one it was issued on.
            assert (ctx.get(dut.advance), ctx.get(dut.step_is_word)) == (previous_issue, previous_word), cycle
            if ctx.get(dut.issue):
                assert credit, cycle  # never without a credit
            if ctx.get(dut.advance):
                runs[previous_run]["steps"].append(ctx.get(dut.step_is_word))
            if ctx.get(dut.request.valid) and ready:
                runs[-1]["requests"].append(ctx.get(dut.request.payload))

            previous_issue, previous_word, previous_run = issue, issue and step[0], len(runs) - 1
            model.edge(credit, ready, clear, begin)
            idle_for = 0 if model.running else idle_for + 1
            await ctx.tick()
            if begin:
                runs.append({"steps": [], "requests": []})
            cycle += 1
            assert cycle < 5000, "the runs did not finish"

    simulate(dut, bench)
    assert restarted
    for k, run in enumerate(runs):
        if k == 1:  # restarted half-way through its map words (a word may issue on the restart's edge)
            taken = len(run["requests"])
            assert words // 2 <= taken <= words // 2 + 1
            assert run["requests"] == list(range(taken)) and run["steps"] == [1] * taken
            continue
        assert run["requests"] == list(range(words))
        assert sum(run["steps"]) == words  # map-word steps
        assert len(run["steps"]) - sum(run["steps"]) == timing.flush_steps  # flush steps
        assert run["steps"] == [1] * words + [0] * timing.flush_steps


def test_step_issue_parameters_are_checked():
    with pytest.raises(ValueError, match="words must be a positive integer"):
        StepIssue(words=0, flush_steps=3)
    with pytest.raises(ValueError, match="flush_steps must be a positive integer"):
        StepIssue(words=4, flush_steps=True)


# --- The beat metadata ----------------------------------------------------------------------------------


def beat_model(parameters):
    """The beat each step completes (step -> its fields), from :func:`completing_steps`."""
    p = parameters
    timing = window_timing(p.map_shape, p.patch_shape, p.lanes)
    Wo, L = p.surface_shape[1], p.lanes
    steps = completing_steps(p.map_shape, p.patch_shape, p.lanes)
    assert len(set(steps.tolist())) == len(steps)  # one beat per step at most
    beats = {}
    for b, step in enumerate(steps.tolist()):
        i, g = divmod(b, timing.out_groups)
        beats[step] = {"i": i, "j": g * L, "count": min(L, Wo - g * L), "last": int(b == len(steps) - 1)}
    return beats


class BeatCarryModel:
    """The beats in the step-synchronous stages (shifted on a step, made not live by a clear) and in
    the term stages (shifted every clock), with the steps and clears counted."""

    def __init__(self, parameters, stages):
        self.beats = beat_model(parameters)
        self.groups = window_timing(parameters.map_shape, parameters.patch_shape, parameters.lanes).groups
        self.sync = [{"live": 0}] * stages.quotient
        self.term = [(0, {"live": 0})] * stages.value  # (fresh, beat), the newest first
        self.fresh, self.step, self.run = 0, 0, -1

    def step_beat(self, step):
        beat = self.beats.get(step)
        return {"live": 1, "emit": int(beat is not None), "run": self.run, **(beat or {})}

    def edge(self, advance, clear):
        self.term = [(self.fresh, self.sync[-1]), *self.term[:-1]]
        self.fresh = int(advance)
        if advance:
            self.sync = [self.step_beat(self.step), *self.sync[:-1]]
            self.step += 1
        if clear:
            self.sync = [{**beat, "live": 0} for beat in self.sync]
            self.step, self.run = 0, self.run + 1

    @property
    def group(self):
        return self.step % self.groups


FIELDS = ("i", "j", "count", "last")


@pytest.mark.parametrize("map_shape, patch_shape, lanes", [
    ((5, 7), (3, 4), 1),  # one lane (never wraps)
    ((5, 8), (3, 4), 2),  # W a multiple of L, wraps
    ((4, 7), (2, 3), 2),  # W not a multiple of L, no wrap
    ((5, 8), (3, 5), 3),  # W not a multiple of L, wraps
    ((4, 10), (3, 4), 3),  # W not a multiple of L, no wrap
    ((4, 9), (2, 3), 3),  # W a multiple of L, wraps
    ((4, 3), (2, 2), 3),  # one group per row, wraps
])
def test_beat_metadata_carries_each_steps_beat_to_the_value_stage(map_shape, patch_shape, lanes):
    p = CorrelatorParameters(map_shape=map_shape, patch_shape=patch_shape, lanes=lanes)
    timing = window_timing(map_shape, patch_shape, lanes)
    dut = BeatMetadata(parameters=p)
    model = BeatCarryModel(p, dut.stages)
    steps = map_shape[0] * timing.groups + timing.flush_steps  # a run's
    rng = np.random.default_rng([map_shape[1], lanes])
    emitted, stale, writes = [], [], []

    async def edge(ctx, advance, clear):
        ctx.set(dut.advance, advance)
        ctx.set(dut.clear, clear)
        assert ctx.get(dut.group) == model.group  # the group of the step being taken
        assert ctx.get(dut.next_group) == (model.group + 1) % model.groups  # the line buffers' read address
        await ctx.tick()
        model.edge(advance, clear)
        fresh, beat = model.term[-1]
        assert ctx.get(dut.fresh) == fresh
        # The queue's write and a step's passing, registers, equal their expressions; the write's next value is
        # the next cycle's write.
        live = ctx.get(dut.fresh) and ctx.get(dut.beat.live)
        assert (ctx.get(dut.write), ctx.get(dut.passed)) == (live and ctx.get(dut.beat.emit), live and not ctx.get(dut.beat.emit))
        writes.append((ctx.get(dut.write), ctx.get(dut.write_next)))
        if not fresh:
            return
        assert ctx.get(dut.beat.live) == beat["live"]
        if not beat["live"]:
            stale.append(beat)
            return
        assert ctx.get(dut.beat.emit) == beat["emit"]
        if beat["emit"]:
            assert {name: ctx.get(getattr(dut.beat, name)) for name in FIELDS} == {name: beat[name] for name in FIELDS}
            emitted.append((beat["run"], beat["i"], beat["j"]))

    async def bench(ctx):
        # Full runs, one cleared half-way (with a step on the clear's edge), each run's steps at random gaps.
        for run, length in enumerate([steps, steps, steps // 2, steps]):
            await edge(ctx, advance=run == 3, clear=True)
            taken = 0
            while taken < length:
                advance = bool(rng.random() < 0.6)
                await edge(ctx, advance, False)
                taken += advance
        for _ in range(dut.stages.value + 2):  # the last run's last beats leave the term stages
            await edge(ctx, False, False)

    simulate(dut, bench)
    beats = len(completing_steps(map_shape, patch_shape, lanes))
    for run in (0, 1, 3):  # every beat of each full run, once (its flush steps carry the last ones out)
        in_run = [b for b in emitted if b[0] == run]
        assert len(in_run) == len(set(in_run)) == beats
    assert len(stale) >= 3 * (dut.stages.quotient - 1)  # the cleared stages went out, not live
    assert all(after[0] == before[1] for before, after in zip(writes, writes[1:])) and sum(w for w, _ in writes) > 0


def test_beat_metadata_refuses_other_parameters():
    with pytest.raises(ValueError, match="parameters must be a CorrelatorParameters"):
        BeatMetadata(parameters=(3, 3))
