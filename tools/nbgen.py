"""Write a notebook from a list of ("md"|"code", source) cells, without outputs (the suite executes them)."""
from __future__ import annotations

import sys
from pathlib import Path

import nbformat


def write(path: str | Path, cells) -> None:
    nb = nbformat.v4.new_notebook()
    nb.metadata["kernelspec"] = {"name": "python3", "display_name": "Python 3", "language": "python"}
    nb.cells = [nbformat.v4.new_markdown_cell(src.strip()) if kind == "md" else nbformat.v4.new_code_cell(src.strip())
                for kind, src in cells]
    nbformat.write(nb, str(path))


if __name__ == "__main__":
    sys.exit("import this module from a notebook script")
