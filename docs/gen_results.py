"""Results pages from the committed JSON (stub)."""
from pathlib import Path


def pages(root: Path) -> dict[str, str]:
    return {"results/index.md": "# Results\n"}
