"""A sudden jump of an aux stream's innovation, and whether it holds.

An aux innovation that jumps from one sample to the next while the baro row
is clean implicates the sensor alone: neither the baro nor the INS (whose
errors are integrals) can make it. One jump is no fault: a spike is gone at
the next sample and the gate has already refused it. A jump that *holds*
(each later sample still, measured from where the stream stood before the
jump, at least ``persist_frac`` of the jump the same way, for ``persist_s``)
is a step of the sensor: the evidence a step's size against the model's sigma cannot
give where the model is wide (a rangefinder's height-proportional term at
35 m is 1 m, its sample-to-sample scatter 5 cm).

Pure: time comes from the samples.
"""

from __future__ import annotations

import math
from dataclasses import dataclass


@dataclass
class Jump:
    t_us: int  # the sample that jumped
    clean: bool  # the baro row was clean then
    size_m: float  # |jump|
    sign: float  # +1 up, -1 down (innovation sense)
    r_pre_m: float  # where the stream stood before the jump (the caller's level)
    last_us: int  # the latest sample that still held it
    samples: int = 0  # later samples that held it
    broken: bool = False  # a later sample gave it back before it held: a spike
    step: bool = False  # it held: a step, whatever the channel takes up of it later

    def follow(self, t_us: int, r_m: float, persist_frac: float, persist_us: int, min_samples: int) -> None:
        """A later sample of the same stream: does the jump still hold? Once it
        has held it stays a step (the channel takes the step up into its height
        and the innovations fade: that is no giving back)."""
        if self.broken or self.step:
            return
        if (r_m - self.r_pre_m) * self.sign >= persist_frac * self.size_m:
            self.samples += 1
            self.last_us = t_us
            self.step = self.samples >= min_samples and t_us - self.t_us >= persist_us
        else:
            self.broken = True


def new_jump(t_us: int, r_m: float, level_m: float, jump_m: float, clean: bool, can_hold: bool = True) -> Jump:
    """A jump of ``jump_m`` from the previous sample, to be followed from
    ``level_m``, where the stream stood; ``can_hold`` False: it names the
    sensor for the innovation test's failure only, never a step by itself."""
    d = r_m - level_m
    return Jump(t_us, clean, jump_m, math.copysign(1.0, d), level_m, t_us, broken=not can_hold)
