"""docs/reference/config.md is the generator's output for today's config: a key added, removed or
re-documented in the dataclasses fails here until `make reference` is run."""
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "scripts"))
import config_reference  # noqa: E402

pytestmark = pytest.mark.fast


def test_config_reference_is_current():
    assert (ROOT / "docs/reference/config.md").read_text() == config_reference.page()


def test_config_reference_lists_every_key():
    from signorini_cli import config
    page = config_reference.page()
    assert all(f"| `{path}` |" in page for path in config.key_paths())
