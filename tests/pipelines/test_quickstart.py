"""The README's quickstart for one's own recordings, copied as written, analyses the example export and writes a
report that opens with the adequacy verdict, then the Wilcoxon table, then β with its HDI; every figure is embedded
and no ground-truth section appears (the recordings have no truth)."""

import re
import shlex
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def quickstart_commands(readme: str) -> list[list[str]]:
    """The ``scioc`` command lines of the README section "Your own recordings", as argument lists."""
    section = readme.split("## Your own recordings", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```sh\n(.*?)```", section, flags=re.S)
    lines = [line.split("#", 1)[0].strip() for block in blocks for line in block.splitlines()]
    return [shlex.split(line) for line in lines if line.startswith("scioc ")]


def test_the_quickstart_commands_are_found():
    commands = quickstart_commands((ROOT / "README.md").read_text())
    assert commands and commands[0][:2] == ["scioc", "analyse"]
    assert quickstart_commands("## Your own recordings\n```sh\nscioc x --y  # z\n```\n## Next\n```sh\nscioc no\n```") \
        == [["scioc", "x", "--y"]]


def test_the_readme_quickstart_produces_the_report(tmp_path, monkeypatch, capsys):
    from scioc.pipelines.cli import main

    (tmp_path / "data").symlink_to(ROOT / "data")  # the README's paths are relative to the repository
    monkeypatch.chdir(tmp_path)
    for argv in quickstart_commands((ROOT / "README.md").read_text()):
        assert main(argv[1:]) in (0, 1), argv  # 1: every human model fails its adequacy checks; still a report
    out = capsys.readouterr().out
    html = (tmp_path / "my-run" / "index.html").read_text()
    order = [html.index("Model adequacy:"), html.index("Wilcoxon matched-pairs signed-rank test"),
             html.index("94 % HDI")]
    assert order == sorted(order), order
    images = re.findall(r"<img [^>]*src=\"([^\"]*)\"", html)
    assert images and all(src.startswith("data:image/png;base64,") for src in images)
    assert "Ground truth" not in html and "true β" not in html
    assert "adequacy at identify: maxent" in out
