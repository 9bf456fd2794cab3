"""LinuxCNC 2.9, the real controller precontour runs its outputs on: configurations for a
machine (:mod:`.config`: joints looped back, or each closed through LinuxCNC's ``pid`` around a
simulated drive, :mod:`.drives`; the stream path for ``streamer``, :mod:`.streamer`), and the
harness that runs a program on LinuxCNC without a screen and records every servo period
(:mod:`.run`). The stage comes before the readers and writers: it knows LinuxCNC's files,
not precontour's programs."""
