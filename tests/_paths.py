"""Where the independent data lies: ``shared/`` beside the repository (as the developers'
machines and CI lay it), never an absolute path."""

from pathlib import Path

SHARED = Path(__file__).resolve().parents[1].parent / "shared"
CROSSPLANT_DATA = SHARED / "crossplant" / "data"
RAV4 = SHARED / "real" / "comma2k19_rav4"
