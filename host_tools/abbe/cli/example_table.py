"""``python -m abbe.cli.example_table DIR``: write the example table (blob + JSON).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from abbe.formats.blob import read_blob, write_blob
from abbe.formats.output import atomic_write
from abbe.formats.table_json import table_to_json
from abbe.model.examples import paper_table
from abbe.model.table import Table


def write_example(out_dir: Path, table: Table | None = None) -> tuple[Path, Path]:
    """Write OUTDIR/model.bin and OUTDIR/model.json (the JSON holds the quantized
    values, so it converts back to the identical blob)."""
    table = paper_table() if table is None else table
    blob = write_blob(table)
    text = json.dumps(table_to_json(read_blob(blob)), indent=2) + "\n"
    out_dir = Path(out_dir)
    bin_path, json_path = out_dir / "model.bin", out_dir / "model.json"
    atomic_write(bin_path, blob)
    atomic_write(json_path, text.encode())
    return bin_path, json_path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m abbe.cli.example_table", description=__doc__.splitlines()[0])
    ap.add_argument("out_dir", type=Path, help="directory for model.bin and model.json")
    args = ap.parse_args(argv)
    for path in write_example(args.out_dir):
        print(path)
    return 0

if __name__ == "__main__":
    sys.exit(main())
