# The accuracy-cost atlas (experiments/accuracy/README.md): `make accuracy [PROFILE=smoke]`. The TGV sweep
# (study.py: tgv2d per kernel and dtype, the harness's cached runs) and the atlas (plot_accuracy.py) are the
# protocol's rules (Makefile: protocol_rules); the atlas gathers the run records of exactly the current runs
# (those the experiments' run stamps list) and runs on every make through $(DELIVER) (lab.deliver): rebuilt
# when a stamp, a record it read, plot_accuracy.py or config.yaml differs from what it was made from.
# What is this folder's own: the atlas's files beside its figure, config.yaml as its input, and the order:
# the atlas reads every experiment's run stamp, so the other targets asked for on the same command line
# (`make -j2 fig9 accuracy`) finish first (order-only: asked alone, it runs no experiment).
_dir := $(patsubst %/,%,$(dir $(lastword $(MAKEFILE_LIST))))
EXTRA.$(_dir).accuracy := runs.csv convergence.png accuracy.md
DEPS.$(_dir).accuracy := $(_dir)/config.yaml

ifeq ($(notdir $(_dir)),accuracy)
ATLAS_OUT := $(addprefix $(RESULTS)/accuracy/,accuracy.png accuracy.pdf runs.csv convergence.png accuracy.md)
ATLAS_AFTER := $(filter-out accuracy report snapshot readme-tables $(ATLAS_OUT),$(MAKECMDGOALS))
$(ATLAS_OUT): | $(ATLAS_AFTER)
accuracy: $(ATLAS_OUT)
endif
