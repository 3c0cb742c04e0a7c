"""Every relative link in README.md and docs/*.md points at a file of the repository, and every ``#anchor`` at a
heading of the file it names (GitHub's heading slugs: lower case, punctuation dropped, spaces to hyphens)."""

import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def slug(heading: str) -> str:
    """GitHub's anchor of a markdown heading."""
    text = re.sub(r"[`*_]|\[([^\]]*)\]\([^)]*\)", r"\1", heading.strip().lower())
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors(path: pathlib.Path) -> set:
    text = re.sub(r"^```.*?^```", "", path.read_text(), flags=re.S | re.M)
    return {slug(h) for h in re.findall(r"^#{1,6}\s+(.*)$", text, re.M)}


def test_slugs_follow_github():
    assert slug("## 3b. A bellows of your own: the wall profile as data".lstrip("# ")) == \
        "3b-a-bellows-of-your-own-the-wall-profile-as-data"
    assert slug("FEM bellows designs (TOML)") == "fem-bellows-designs-toml"
    assert slug("3b. An identification experiment on the rig (`bellows experiment`)") == \
        "3b-an-identification-experiment-on-the-rig-bellows-experiment"


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_relative_links_resolve(doc):
    text = re.sub(r"^```.*?^```", "", doc.read_text(), flags=re.S | re.M)
    bad = []
    for target in LINK.findall(text):
        if re.match(r"[a-z]+:", target):
            continue                                      # http(s), mailto: not checked here
        file, _, anchor = target.partition("#")
        path = (doc.parent / file).resolve() if file else doc
        if not path.exists():
            bad.append(f"{target}: no file {path.relative_to(ROOT) if ROOT in path.parents else path}")
        elif anchor and path.suffix == ".md" and anchor not in anchors(path):
            bad.append(f"{target}: no heading with anchor #{anchor} in {path.name}")
    assert not bad, "\n".join(bad)
