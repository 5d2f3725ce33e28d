"""Train one model (or resume it, or find it current: sitl/train.py), then evaluate it on the test
split (sitl/evaluate.py), in one process: what `make table1` runs per model. One LagrangeBench start-up
(about 6 s of imports) instead of two; each step keeps its own cache and messages.

    .venv-lb/bin/python sitl/fit.py --profile smoke --model sitl
"""
from sitl import evaluate  # first: it imports sitl.common, which sets up LagrangeBench
from sitl import settings as S
from sitl import train
from lab.cli import profile_main


def options(ap):
    ap.add_argument("--model", required=True, choices=S.MODELS)


def main(args):
    exp = S.load(args.profile)
    train.train(exp, args.results, args.model)
    evaluate.evaluate(exp, args.results, args.model)


if __name__ == "__main__":
    profile_main(main, __doc__, options)
