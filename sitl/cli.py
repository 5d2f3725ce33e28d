"""The command line every sitl script shares: `--profile` (default paper) and `--results`
(default results/<profile>), parsed into the validated experiment settings."""
import argparse

from sitl import settings as S


def profile_args(doc: str, argv=None, add=None):
    """(exp, results folder, parsed args); `add(parser)` adds a script's own options."""
    ap = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--profile", default="paper")
    ap.add_argument("--results", default=None)
    if add is not None:
        add(ap)
    args = ap.parse_args(argv)
    return S.load(args.profile), args.results or f"results/{args.profile}", args
