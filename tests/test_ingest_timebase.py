"""The time stage on its own (mavnav/ingest/timebase.py): the steps it returns, in order."""

from __future__ import annotations

from mavnav.ingest.timebase import SETTLED, ClockStepped, NewBoot, Placed, Refused, TimeBase

AP = 1  # the autopilot's component


def run(tb: TimeBase, steps) -> list:
    """Take the steps one by one, as the normaliser does (a NewBoot starts the new boot)."""
    out = []
    for s in steps:
        out.append(s)
        if type(s) is NewBoot:
            tb.new_boot(s.t_us, s.recv_s)
    return out


def placed(steps) -> list:
    return [(s.t_us, s.what, s.f) for s in steps if type(s) is Placed]


def steady(tb: TimeBase, n: int = 20, t0_us: int = 100_000_000, dt_us: int = 100_000, r0: float = 1000.0) -> None:
    """``n`` ATTITUDE-like messages of the autopilot, every ``dt_us``, received as sent."""
    for k in range(n):
        run(tb, tb.boot_ms(t0_us + k * dt_us, r0 + k * dt_us * 1e-6, AP, "attitude", k))


def test_a_message_on_the_clock_is_placed_then_settled():
    tb = TimeBase(reboot_jump_s=2.0)
    assert list(tb.boot_ms(5_000_000, 10.0, AP, "attitude", "q")) == [Placed(5_000_000, 10.0, "attitude", "q"), SETTLED]
    assert tb.clock.last_t_us == 5_000_000


def test_a_reboot_starts_the_new_boot_before_its_first_messages():
    tb = TimeBase(reboot_jump_s=2.0)
    steady(tb)
    r = 1002.0
    out = []
    for k in range(6):  # a time base 90 s back: candidates, adopted after 5 messages over 1 s
        out += run(tb, tb.boot_ms(10_000_000 + k * 250_000, r + k * 0.25, AP, "attitude", f"n{k}"))
    kinds = [type(s).__name__ if s is not SETTLED else "SETTLED" for s in out]
    assert kinds[0] == "NewBoot" and out[0] == NewBoot(10_000_000, r)
    assert placed(out)[:5] == [(10_000_000 + k * 250_000, "attitude", f"n{k}") for k in range(5)]
    assert tb.clock.boot == 1


def test_an_isolated_old_burst_is_refused_as_stale():
    tb = TimeBase(reboot_jump_s=2.0)
    steady(tb)
    last = tb.clock.last_t_us
    out = run(tb, tb.boot_ms(last - 5_000_000, 1002.0, AP, "attitude", "old"))
    assert out == []  # held as a candidate
    out = run(tb, tb.boot_ms(last + 100_000, 1002.1, AP, "attitude", "new"))
    assert isinstance(out[0], Refused) and out[0].kind == "stale" and out[0].t_us == last - 5_000_000
    assert placed(out) == [(last + 100_000, "attitude", "new")]
    assert tb.clock.boot == 0


def test_a_small_step_back_moves_later_times_on():
    tb = TimeBase(reboot_jump_s=2.0)
    steady(tb)
    last = tb.clock.last_t_us
    out = []
    for k in range(5):  # 1 s back (less than reboot_jump_s), catching up: a clock step
        out += run(tb, tb.boot_ms(last - 1_000_000 + k * 300_000, 1002.0 + k * 0.3, AP, "attitude", k))
    steps = [s for s in out if type(s) is ClockStepped]
    assert len(steps) == 1 and "stepped back 1.00 s" in steps[0].text
    times = [t for t, _, _ in placed(out)]
    assert times[0] == last + 1_000 and times == sorted(times)  # just after the last old time, in order


def test_followers_wait_for_the_verdict_and_land_on_the_new_boot():
    tb = TimeBase(reboot_jump_s=2.0)
    steady(tb)
    r = 1002.0
    out = run(tb, tb.boot_ms(10_000_000, r, AP, "attitude", "c0"))
    # an untimed message and another component's message during the candidates: they wait
    assert run(tb, tb.untimed(r + 0.05, "rangefinder", "rf", "RANGEFINDER")) == []
    assert run(tb, tb.stream(("boot_ms", 2, "distance_sensor"), 7_000_000, r + 0.06, "distance_sensor", "ds")) == []
    for k in range(1, 5):
        out += run(tb, tb.boot_ms(10_000_000 + k * 300_000, r + k * 0.3, AP, "attitude", f"c{k}"))
    assert type(out[0]) is NewBoot
    whats = [w for _, w, _ in placed(out)]
    assert whats[:5] == ["attitude"] * 5 and "rangefinder" in whats
    rf = next(t for t, w, _ in placed(out) if w == "rangefinder")
    assert rf == 10_000_000 + 50_000  # placed on the new time base by its receive time


def test_untimed_before_any_time_is_refused():
    tb = TimeBase(reboot_jump_s=2.0)
    [s] = list(tb.untimed(1.0, "rangefinder", "rf", "RANGEFINDER"))
    assert type(s) is Refused and s.kind == "no_time" and "RANGEFINDER before any timed message" in s.detail


def test_open_candidates_are_refuted_at_the_end():
    tb = TimeBase(reboot_jump_s=2.0)
    steady(tb)
    assert run(tb, tb.boot_ms(1_000_000, 1002.0, AP, "attitude", "x")) == []
    [s] = list(tb.finish())
    assert type(s) is Refused and "at the end of the stream" in s.detail
    assert list(tb.finish()) == []
