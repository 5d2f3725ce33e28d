"""The reproduction at a glance: `make report`, `make all`'s time plan, `make snapshot` and
`make readme-tables` (report/README.md).

One module per concept:

  paper.py        docs/paper_values.yaml: the paper's values, references, tolerances per target
  trace.py        a number and where it comes from (file, row, column); resolving a trace
  fmt.py          how numbers are written
  checks.py       a headline number beside the paper's value, its tolerance and verdict
  timing.py       wall time and ms per step of a target's runs; the time plan's estimates
  plan.py         `make all`'s plan: every target in dependency order with its expected time
  provenance.py   commit, date, CPU / GPU, versions, profile
  atlas.py        the accuracy atlas's cheapest-setting table
  stability.py    the stability matrix
  model.py        the report's content: one entry per target (run or not run)
  figures.py      figures copied (and compressed) beside the report
  html.py, markdown.py   the two renderings
  build.py        `python -m report.build`: results/<profile>/report/{index.html, report.md}
  snapshot.py     `make snapshot`: docs/results/<profile>/
  readme_tables.py  `make readme-tables`: README tables between <!-- table:NAME --> markers
"""
