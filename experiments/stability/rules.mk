# Stability suite (experiments/stability/README.md): `make stability [PROFILE=smoke]`. The runs (each case
# a run of study.py, cached by the harness; a blow-up or an error is the case's outcome, never a failed
# make) and the table are the protocol's rules (Makefile: protocol_rules): plot_stability.py judges every
# case and writes the table beside its figure. What is this folder's own: the table's files
# (stability.csv, stability.md) and config.yaml as an input of the table (a case's criteria, expected
# and note are out of its run's key: editing them re-judges without re-running).
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
EXTRA.$(_dir).stability := stability.csv stability.md
DEPS.$(_dir).stability := $(_dir)/config.yaml

ifeq ($(notdir $(_dir)),stability)
stability: $(addprefix $(RESULTS)/stability/,stability.csv stability.md)
endif
