"""abbe history on SQLite and PostgreSQL: add (strict, atomic, once), show, report,
export read back by independent readers, the fleet (two writers, a reader), migrations."""

from __future__ import annotations

import csv
import json
import multiprocessing
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import sqlalchemy as sa

from abbe.cli.entry import main
from conftest import ballbar_variant


def _count(db: str, table: str) -> int:
    from abbe.history.database import open_database
    base = open_database(db)
    try:
        with base.read() as conn:
            return conn.execute(sa.text(f"SELECT count(*) FROM {table}")).scalar_one()
    finally:
        base.close()


def _add_full(db: str, outputs: Path, date: str = "2026-01-05") -> int:
    return main(["history", "--db", db, "add", str(outputs / "fit"), str(outputs / "diagnose"),
                 str(outputs / "ballbar.json"), str(outputs / "iso_x.json"), "--axis", "X",
                 "--date", date, "--operator", "ana", "--instrument", "XL-80", "--temp-c", "20.1"])


def test_add_reads_every_output_and_refuses_the_same_campaign(db, outputs, capsys):
    assert _add_full(db, outputs) == 0
    fit = json.loads((outputs / "fit" / "model.json").read_text())
    diag = json.loads((outputs / "diagnose" / "diagnose.json").read_text())
    bb = json.loads((outputs / "ballbar.json").read_text())
    iso = json.loads((outputs / "iso_x.json").read_text())
    from abbe.history.database import open_database
    base = open_database(db)
    with base.read() as conn:
        vals = dict(conn.execute(sa.text("SELECT series, value FROM results")).all())
        tables = conn.execute(sa.text("SELECT source, crc32, size_bytes FROM tables")).all()
        inputs = conn.execute(sa.text("SELECT role, sha256 FROM inputs")).all()
        camp = conn.execute(sa.text("SELECT operator, measured_at FROM campaigns")).one()
    base.close()
    assert vals["ballbar G XY F200 bi"] == bb["bidirectional"]["G_um"]
    assert vals["iso230-2 B X bi"] == iso["B_um"]  # the iso230-2 JSON wins over the fit's
    assert vals["iso230-2 B Y bi"] == fit["axes"]["Y"]["iso230_2"]["B_um"]
    assert vals["fit backlash X"] == fit["axes"]["X"]["backlash"]["mean_reversal_um"]
    for e in diag["effects"]:
        assert vals[f"diagnose {e['key']}"] == e["value"]
    assert {s for s, _, _ in tables} == {"fit", "diagnose"}
    assert f"0x{dict((s, c) for s, c, _ in tables)['fit']:08X}" == fit["table"]["crc32"]
    # the measurement files' hashes from the fit's provenance
    assert fit["provenance"]["inputs"]["laser.X"]["sha256"] in {h for _, h in inputs}
    assert camp[0] == "ana" and str(camp[1]).startswith("2026-01-05")
    n = _count(db, "results")
    capsys.readouterr()
    assert _add_full(db, outputs, date="2026-02-01") == 2
    assert "already in the database as campaign" in capsys.readouterr().err
    assert _count(db, "results") == n and _count(db, "campaigns") == 1


def test_a_failed_add_leaves_nothing(db, outputs, tmp_path, capsys):
    bad = json.loads((outputs / "ballbar.json").read_text())
    bad["cw"]["G_um"] = "12.5"
    (tmp_path / "bad.json").write_text(json.dumps(bad, indent=2))
    assert main(["history", "--db", db, "add", str(outputs / "fit"), str(tmp_path / "bad.json")]) == 2
    err = capsys.readouterr().err
    assert "bad.json:" in err and "cw.G_um" in err and "expected a number" in err
    # a failure inside the transaction, after the campaign row went in: all rolled back
    assert main(["history", "--db", db, "add", str(outputs / "ballbar.json"),
                 "--machine", "another"]) == 0  # the database exists; vmc500 is new in it
    from abbe.history.database import open_database
    from abbe.history.ingest import Result, read_campaign
    from abbe.history.store import Meta, add_campaign
    before = {t: _count(db, t) for t in ("machines", "campaigns", "results", "tables", "inputs")}
    c = read_campaign([str(outputs / "fit")], {}, None)
    # the last result has no unit: the database refuses that row (NOT NULL) inside the
    # transaction, after the machine, campaign, inputs and the other results went in
    c.results.append(Result("bad", "fit", "q", 1.0, None))
    base = open_database(db)
    try:
        with pytest.raises(sa.exc.IntegrityError):
            add_campaign(base, c, Meta(measured_at=__import__("datetime").datetime(2026, 1, 1)))
    finally:
        base.close()
    assert {t: _count(db, t) for t in before} == before


def test_bad_inputs_are_refused_with_their_place(outputs, tmp_path, capsys):
    db = str(tmp_path / "h.sqlite")
    fit = tmp_path / "fit"
    shutil.copytree(outputs / "fit", fit)
    other = bytearray((outputs / "diagnose" / "model.bin").read_bytes())
    (fit / "model.bin").write_bytes(other)  # a table of another result beside this model.json
    assert main(["history", "--db", db, "add", str(fit)]) == 2
    assert "does not match model.bin" in capsys.readouterr().err
    assert not Path(db).exists()  # nothing read, no database created
    (tmp_path / "empty").mkdir()
    assert main(["history", "--db", db, "add", str(tmp_path / "empty")]) == 2
    assert "no abbe output here" in capsys.readouterr().err
    assert main(["history", "--db", db, "add", str(outputs / "iso_x.json")]) == 2
    assert "--axis" in capsys.readouterr().err
    assert main(["history", "--db", db, "add", str(outputs / "ballbar.json")]) == 2
    assert "--machine" in capsys.readouterr().err
    nan = (outputs / "ballbar.json").read_text().replace('"H_um": ', '"H_um": NaN, "x": ', 1)
    (tmp_path / "nan.json").write_text(nan)
    assert main(["history", "--db", db, "add", str(tmp_path / "nan.json"), "--machine", "m"]) == 2
    assert "nan.json" in capsys.readouterr().err
    assert main(["history", "--db", db, "add", str(outputs / "ballbar.json"), "--machine", "m",
                 "--date", "2026-13-01"]) == 2
    assert "--date" in capsys.readouterr().err
    (tmp_path / "text.sqlite").write_text("hello")
    assert main(["history", "--db", str(tmp_path / "text.sqlite"), "show"]) == 2
    assert "not an SQLite database" in capsys.readouterr().err
    assert main(["history", "--db", str(tmp_path / "none.sqlite"), "show"]) == 2
    assert not (tmp_path / "none.sqlite").exists()


def test_unreachable_server_is_exit_1(tmp_path, capsys):
    url = f"postgresql://abbe@/x?host={tmp_path}&port=1"
    assert main(["history", "--db", url, "show"]) == 1
    err = capsys.readouterr().err
    assert "cannot open the history database" in err


def test_show_report_export(db, outputs, tmp_path, capsys):
    for i in range(5):
        assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path / "v", i)),
                     "--machine", "m1", "--date", f"2025-{i + 1:02d}-10"]) == 0
    # a step: the last campaign's G jumps 10 um
    assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path / "v", 1000)),
                 "--machine", "m1", "--date", "2025-07-10"]) == 0
    capsys.readouterr()
    assert main(["history", "--db", db, "show", "m1", "--last", "3"]) == 0
    out = capsys.readouterr().out
    row = next(ln for ln in out.splitlines() if ln.startswith("ballbar G XY F200 bi"))
    assert row.split()[-1] == "band,limit"  # the step left the band and passed 25 um
    assert main(["history", "--db", db, "report", "m1", "-o", str(tmp_path / "rep")]) == 0
    page = (tmp_path / "rep" / "index.html").read_text()
    assert "Current alerts (campaign 6" in page and "ballbar G XY F200 bi [band]" in page
    # every picture the page shows is there and is a PNG (read with the standard parser)
    from html.parser import HTMLParser

    class Imgs(HTMLParser):
        srcs: list = []

        def handle_starttag(self, tag, attrs):
            if tag == "img":
                self.srcs.append(dict(attrs)["src"])
    parser = Imgs()
    parser.feed(page)
    assert parser.srcs and sorted(parser.srcs) == sorted(
        p.name for p in (tmp_path / "rep").glob("trend_*.png"))
    assert all((tmp_path / "rep" / s).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for s in parser.srcs)
    # exports, read back with the standard library's readers
    assert main(["history", "--db", db, "export", "m1", "-o", str(tmp_path / "m1.csv")]) == 0
    assert main(["history", "--db", db, "export", "-o", str(tmp_path / "all.json")]) == 0
    rows = list(csv.DictReader((tmp_path / "m1.csv").open()))
    g = sorted(float(r["value"]) for r in rows if r["series"] == "ballbar G XY F200 bi")
    base = json.loads((outputs / "ballbar.json").read_text())["bidirectional"]["G_um"]
    assert g == pytest.approx(sorted([round(base + 0.01 * i, 4) for i in [0, 1, 2, 3, 4, 1000]]))
    assert {r["unit"] for r in rows} == {"um"}
    doc = json.loads((tmp_path / "all.json").read_text())
    assert doc["format"] == "abbe-history" and len(doc["machines"][0]["campaigns"]) == 6
    assert _count(db, "exports") == 3


def _writer(db: str, outputs: Path, tmp: Path, start: int, n: int, q) -> None:
    rcs = [main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp, i)),
                 "--machine", "fleet", "--date", "2025-01-01"]) for i in range(start, start + n)]
    q.put(rcs)


def _reader(db: str, stop, q) -> None:
    """Read (campaign, number of results) until stopped; report any half campaign seen."""
    from abbe.history.database import open_database
    base = open_database(db)
    seen, bad = 0, []
    while not stop.is_set():
        with base.read() as conn:
            rows = conn.execute(sa.text(
                "SELECT c.id, count(r.id) FROM campaigns c LEFT JOIN results r "
                "ON r.campaign_id = c.id GROUP BY c.id")).all()
        seen = max(seen, len(rows))
        bad += [r for r in rows if r[1] != 7]
    base.close()
    q.put((seen, bad))


def test_two_writers_lose_nothing_and_a_reader_never_sees_half(db, outputs, tmp_path):
    assert main(["history", "--db", db, "add", str(ballbar_variant(outputs, tmp_path, 999)),
                 "--machine", "fleet", "--date", "2025-01-01"]) == 0
    ctx = multiprocessing.get_context("fork")
    q, stop = ctx.Queue(), ctx.Event()
    reader = ctx.Process(target=_reader, args=(db, stop, q))
    reader.start()
    ws = [ctx.Process(target=_writer, args=(db, outputs, tmp_path / f"w{k}", 100 * k, 12, q))
          for k in (1, 2)]
    for w in ws:
        w.start()
    for w in ws:
        w.join(300)
    stop.set()
    reader.join(60)
    got = [q.get(timeout=10) for _ in range(3)]
    rcs = [x for x in got if isinstance(x, list)]
    seen, bad = next(x for x in got if isinstance(x, tuple))
    assert rcs == [[0] * 12, [0] * 12]
    assert bad == [] and seen >= 1
    assert _count(db, "campaigns") == 25 and _count(db, "results") == 25 * 7
    # both adding the same campaign at once: exactly one succeeds
    same = ballbar_variant(outputs, tmp_path / "same", 5000)
    ctx2 = [ctx.Process(target=_writer_same, args=(db, same, q)) for _ in range(2)]
    for p in ctx2:
        p.start()
    for p in ctx2:
        p.join(120)
    assert sorted(q.get(timeout=10) for _ in range(2)) == [0, 2]
    assert _count(db, "campaigns") == 26


def _writer_same(db: str, path: Path, q) -> None:
    q.put(main(["history", "--db", db, "add", str(path), "--machine", "fleet",
                "--date", "2025-01-02"]))


def test_migration_from_the_first_schema(db, outputs, capsys):
    from abbe.history.database import _sqlite_engine, resolve, upgrade
    loc = resolve(db)
    sa_engine = (_sqlite_engine(sa, loc, "rwc") if loc.sqlite_file else sa.create_engine(loc.url))
    upgrade(sa_engine, "0001")
    with sa_engine.begin() as conn:  # a campaign stored by an abbe of the first schema
        conn.execute(sa.text("INSERT INTO machines (name, created_at) VALUES "
                             "('old', '2024-01-01 00:00:00')"))
        mid = conn.execute(sa.text("SELECT id FROM machines")).scalar_one()
        conn.execute(sa.text(
            "INSERT INTO campaigns (machine_id, measured_at, added_at, kinds, source, "
            "content_sha256, abbe_version) VALUES (:m, '2024-01-02 00:00:00', "
            "'2024-01-02 00:00:00', 'ballbar', 'x', :h, '0.0.9')"), {"m": mid, "h": "a" * 64})
        cid = conn.execute(sa.text("SELECT id FROM campaigns")).scalar_one()
        conn.execute(sa.text("INSERT INTO results (campaign_id, series, source, quantity, value, "
                             "unit) VALUES (:c, 'ballbar G XY F200 bi', 'ballbar', 'G', 12.5, "
                             "'um')"), {"c": cid})
        cols = [c["name"] for c in sa.inspect(conn).get_columns("campaigns")]
    assert "note" not in cols
    sa_engine.dispose()
    capsys.readouterr()
    assert main(["history", "--db", db, "show", "old"]) == 2
    assert "abbe history migrate" in capsys.readouterr().err
    assert main(["history", "--db", db, "migrate"]) == 0
    assert "revision 0004" in capsys.readouterr().out
    assert main(["history", "--db", db, "show", "old"]) == 0
    assert "12.5" in capsys.readouterr().out
    assert main(["history", "--db", db, "add", str(outputs / "ballbar.json"), "--machine", "old",
                 "--note", "after the migration"]) == 0
    from abbe.history.database import open_database
    base = open_database(db)
    with base.read() as conn:
        notes = conn.execute(sa.text("SELECT id, note FROM campaigns ORDER BY id")).all()
        from alembic.autogenerate import compare_metadata
        from alembic.runtime.migration import MigrationContext
        from abbe.history.schema import metadata
        diff = compare_metadata(MigrationContext.configure(conn), metadata)
    base.close()
    assert [n for _, n in notes] == [None, "after the migration"]
    assert diff == []  # the migrations build exactly the schema the code uses


def test_history_without_the_extra(tmp_path):
    """Without SQLAlchemy: abbe works; abbe history says what to install (exit 2)."""
    code = ("import sys; sys.modules['sqlalchemy'] = None; sys.modules['alembic'] = None\n"
            "from abbe.cli.entry import main\n"
            f"sys.exit(main(['history', '--db', {str(tmp_path / 'h.sqlite')!r}, 'show']))")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "pip install 'abbe[history]'" in r.stderr
    r = subprocess.run([sys.executable, "-c", "import sys; sys.modules['sqlalchemy'] = None\n"
                        "from abbe.cli.entry import main; sys.exit(main(['iso230-2', "
                        f"{str(Path(__file__).resolve().parents[3] / 'examples/vmc500/laser/x.csv')!r}]))"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and "B" in r.stdout


def test_a_demo_folder_is_read_as_fit_and_diagnose(outputs, tmp_path):
    """abbe demo -o OUT writes OUT/fit/, OUT/diagnose/ and OUT/diagnose.json (the same
    bytes as OUT/diagnose/diagnose.json), beside plots and index.html."""
    from abbe.history.ingest import read_campaign
    demo = tmp_path / "demo"
    shutil.copytree(outputs / "fit", demo / "fit")
    shutil.copytree(outputs / "diagnose", demo / "diagnose")
    shutil.copy(outputs / "diagnose" / "diagnose.json", demo / "diagnose.json")
    (demo / "index.html").write_text("<html></html>")
    (demo / "notes.json").write_text('{"not": "an abbe output"}')
    c = read_campaign([str(demo)], {}, None)
    assert c.kinds == ["diagnose", "fit"] and c.machine == "vmc500"
    assert sorted(s for s, _, _ in c.tables) == ["diagnose", "fit"]
    assert len([r for r in c.results if r.series == "diagnose gap rms before"]) == 1
    # the folder read twice gives the same campaign hash; another table does not
    assert read_campaign([str(demo)], {}, None).content_sha256() == c.content_sha256()
    (demo / "fit" / "model.json").write_text((demo / "fit" / "model.json").read_text()
                                             .replace('"machine"', '"machine" ', 1))
    assert read_campaign([str(demo)], {}, None).content_sha256() != c.content_sha256()
