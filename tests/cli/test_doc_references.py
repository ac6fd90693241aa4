"""Every relative link and anchor in the Markdown files resolves, and every repository path a doc, a config or a
script cites exists: a renamed page, section or file cannot leave a dead reference behind."""
from __future__ import annotations

import re
import subprocess
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
TOP_FOLDERS = ("envs", "modules", "vision", "robot_sim", "speech", "logs", "pipelines", "fileio", "tests", "bench",
               "docs", "results", "scripts")
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)(?:\s+\"[^\"]*\")?\)")
HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
CITED = re.compile(rf"(?<![\w/.-])((?:{'|'.join(TOP_FOLDERS)})/[\w./-]*\w)")
#: a path after one of these is where a command writes, not a file that exists
OUTPUT_OPTIONS = re.compile(r"(--out|-o|--claims|--runs|--screenshots|>)\s+$")
FENCE = re.compile(r"^\s*(```|~~~)")


def tracked(*suffixes: str) -> list[Path]:
    names = subprocess.run(["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True).stdout.split()
    return [ROOT / name for name in names if name.endswith(suffixes) and (ROOT / name).is_file()]


def prose(text: str) -> list[tuple[int, str]]:
    """(line number, line) outside fenced code blocks (links there are examples, not links)."""
    lines, inside = [], False
    for number, line in enumerate(text.splitlines(), 1):
        if FENCE.match(line):
            inside = not inside
        elif not inside:
            lines.append((number, line))
    return lines


def slug(heading: str) -> str:
    """GitHub's anchor of a heading: its text lower-cased, punctuation dropped, spaces as hyphens."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading)  # a link in a heading: its text
    text = re.sub(r"[^\w\- ]", "", text.strip().lower())
    return text.replace(" ", "-")


@cache
def anchors(page: Path) -> frozenset[str]:
    found, seen = set(), {}
    for _, line in prose(page.read_text(encoding="utf-8")):
        heading = HEADING.match(line)
        if heading:
            name = slug(heading.group(2))
            count = seen.get(name, 0)
            seen[name] = count + 1
            found.add(name if count == 0 else f"{name}-{count}")
        found.update(re.findall(r"<a\s+(?:id|name)=\"([^\"]+)\"", line))
    return frozenset(found)


def test_every_relative_link_and_anchor_resolves() -> None:
    broken = []
    for page in tracked(".md"):
        for number, line in prose(page.read_text(encoding="utf-8")):
            for target in LINK.findall(re.sub(r"`[^`]*`", "", line)):
                if re.match(r"[a-z][a-z0-9+.-]*:", target):  # https:, mailto:
                    continue
                path, _, anchor = target.partition("#")
                destination = (page.parent / path).resolve() if path else page
                where = f"{page.relative_to(ROOT)}:{number}: {target}"
                if not destination.exists():
                    broken.append(f"{where} (no such file)")
                elif anchor and destination.suffix == ".md" and anchor not in anchors(destination):
                    broken.append(f"{where} (no heading #{anchor} in {destination.relative_to(ROOT)})")
    assert not broken, "dead links:\n" + "\n".join(broken)


def cited_paths(text: str) -> list[tuple[int, str]]:
    """(line, path) of each repository path the text cites, outputs of example commands left out."""
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        for match in CITED.finditer(line):
            after = line[match.end():match.end() + 1]
            if OUTPUT_OPTIONS.search(line[:match.start()]) or (after and after in "*{<"):  # an output, a glob
                continue
            found.append((number, match.group(1)))
    return found


def exists(path: str, citing: Path) -> bool:
    candidates = [ROOT / path, citing.parent / path]
    module, _, attribute = path.rpartition(".")  # modules/guided_mcts.TurnFeatures: a module's attribute
    if attribute[:1].isupper():
        candidates.append(ROOT / f"{module}.py")
    return any(candidate.exists() for candidate in candidates)


def test_every_path_a_doc_config_or_script_cites_exists() -> None:
    missing = []
    sources = tracked(".md", ".sh", ".toml") + [path for path in tracked(".yaml", ".yml")
                                                if path.is_relative_to(ROOT / "pipelines" / "configs")]
    for source in sources:
        for number, path in cited_paths(source.read_text(encoding="utf-8")):
            if not exists(path, source):
                missing.append(f"{source.relative_to(ROOT)}:{number}: {path}")
    assert not missing, "cited paths that do not exist:\n" + "\n".join(missing)


def test_the_checks_find_what_they_look_for(tmp_path: Path) -> None:
    """The checkers see links, anchors and cited paths (a checker that sees nothing cannot fail)."""
    assert slug("`ncbot reproduce`") == "ncbot-reproduce" and slug("Your own comparison: `ncbot compare`") == \
        "your-own-comparison-ncbot-compare"
    assert "ncbot-reproduce" in anchors(ROOT / "docs" / "reproduction.md")
    text = "see docs/cli.md and `bench/studies/exact_curve.py`; ncbot ladder --out results/ladder\n```\ndocs/x.md\n```"
    assert [path for _, path in cited_paths(text)] == ["docs/cli.md", "bench/studies/exact_curve.py", "docs/x.md"]
    assert LINK.findall("[a](b.md#c) and [d](https://e)") == ["b.md#c", "https://e"]
