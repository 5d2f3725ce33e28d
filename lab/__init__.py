"""The harness: what runs the physics core (`sph`) for an experiment, and never the other way round.

  configtools.py   the config API in one import: typed.py (frozen config dataclasses from mappings),
                   yamlfile.py (strict YAML), profiles.py (`inherit`, errors naming file, profile, key)
  keys.py          cache keys: config digests, code fingerprints without docstrings and comments
  runs.py          the cached run: skip a current run, resume a partial one, set aside a stale one
  record.py        the run record every experiment writes (what `make accuracy` gathers)
  tables.py        metrics tables (csv), rewritten from the current config's runs
  io.py, xdmf.py   trajectory files (LagrangeBench layout, resumable) and their ParaView sidecars
  animate.py       a short GIF of a trajectory
  figures.py       what the plot scripts share: method colours and dashes, figure files, table copies
  cli.py           a script's command line (`profile_main`) and one-line errors (`main_guard`)
  stamp.py         make stamps: a run step's manifest of exactly the current runs (note_current)
  deliver.py       deliverables verified on every make: re-made when their inputs or files differ
  experiment.py    the experiment-folder protocol (config.yaml + study.py + plot_<name>.py): the rest
  protocol.py      what a study may declare besides its four names: a cached Start, its Table
  layout.py        where a study writes (results/<profile>/<name>/<method>_<tag>/) and its code key
  study.py         a study's methods (named solver variants) and the checks of its settings
  cost.py          the cost of an experiment's runs from a short run of each, without running them
  lock.py, atomic.py, other_load.py   one writer per folder, atomic writes, the load beside a timing
  interrupt.py     Ctrl-C never lost in a garbage-collector callback (installed here, before JAX)
XLA's CPU flag is the core's (`sph.set_cpu_defaults`); the entry points (`cli.main_guard`) set it.

Imports go from here to the core only (`sph.errors`, `sph.simulate`, ...). Which of these modules can
change a run's numbers, and so enter its cache key, is `keys.NUMBER_NEUTRAL`'s complement (the study
modules, which set up scenes and starts).
"""
from . import interrupt as _interrupt

_interrupt.install()
