"""docs/paper_values.yaml: every value the report compares with names its source, so a reader can
open it (the paper's text or figure, the authors' code, LagrangeBench, the literature), and the
report calls a value "reference", not "paper", where it is not the paper's own."""
import copy

import pytest

from report import checks, markdown, paper


@pytest.fixture(scope="module")
def values():
    return paper.load()


def test_every_value_and_reference_has_a_source_kind_and_locator(values):
    assert paper.problems(values) == []
    compared = [(n, cid, c) for n, t in values["targets"].items() for cid, c in (t.get("checks") or {}).items()
                if c.get("paper") is not None]
    assert compared, "the file compares with published values"
    for name, cid, c in compared:
        assert c["source"]["kind"] in paper.KINDS and c["source"]["locator"].strip(), (name, cid)


@pytest.mark.parametrize("damage", ["no source", "no locator", "unknown kind", "paper_where", "reference",
                                    "target locator"])
def test_an_entry_without_kind_or_locator_fails(values, damage):
    v = copy.deepcopy(values)
    check = v["targets"]["fig2"]["checks"]["a_gd"]
    if damage == "no source":
        del check["source"]
    elif damage == "no locator":
        check["source"] = {"kind": "authors_code"}
    elif damage == "unknown kind":
        check["source"] = {"kind": "somewhere", "locator": "x"}
    elif damage == "paper_where":
        check["paper_where"] = "Fig. 2"
    elif damage == "reference":
        v["references"]["ghia"] = "Ghia et al. (1982)"  # text without kind and locator
    else:
        v["targets"]["fig5"]["paper"] = {"where": "Fig. 5"}
    assert paper.problems(v), damage


def test_no_locator_names_a_section_the_paper_lacks(values):
    """The inverse problem is in Sec. 3 and the 2D TGV in App. A.1; there is no Sec. 4.1."""
    text = paper.PAPER_VALUES.read_text()
    assert "Sec. 4.1" not in text
    assert values["targets"]["fig2"]["paper"]["locator"].startswith("Sec. 3")
    assert values["targets"]["fig5"]["paper"]["locator"].startswith("App. A.1")


def test_the_value_column_is_called_reference_where_the_value_is_not_the_papers(values, tmp_path):
    def result(kind):
        tgt, cid = ("table1", "sitl_mse20") if kind == "paper_text" else ("fig2", "a_gd")
        return checks.evaluate(tgt, cid, values["targets"][tgt]["checks"][cid], tmp_path, values)

    table, notebook = result("paper_text"), result("authors_code")
    assert table.is_paper and table.source_label == "paper: Table 1"
    assert not notebook.is_paper and notebook.source_label.startswith("authors' code: tumaer/jax-sph notebooks/")
    assert markdown.value_header([table]) == "paper"
    assert markdown.value_header([table, notebook]) == "reference"
    assert markdown.value_word(notebook) == "reference"
