"""``abbe table cgen`` of a format 1.3 table (a thermal block): the generated C, compiled
with the C library, loads through ``abbe_thermal_load`` and its runtime (f32 and q)
reproduces the Python reference (``abbe.model.thermal.evaluate`` of the table's quantised
model) sample by sample; the header refuses a library without the thermal block; a broken
1.3 table is refused with its file named and nothing written.

The model is the one identified on the real record (examples/spindle_thermal/thermal.json,
17 inputs, 5 channels) on the paper table, with a stuck check on one input (bytes the
golden block leaves 0); the inputs a warm-up / cool-down record under speed steps written
here (not the golden vectors' record)."""

from __future__ import annotations

import json
import shutil
import subprocess
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from abbe.cli.entry import main as cli
from abbe.formats.thermal_blob import read_thermal_blob, write_thermal_blob
from abbe.model.thermal import SPEED, evaluate, from_dict

REPO = Path(__file__).resolve().parents[3]
N = 400

pytestmark = pytest.mark.skipif(shutil.which("cc") is None, reason="no C compiler")

MAIN_C = r"""
#include <stdio.h>
#include "abbe/abbe.h"
#include "abbe/thermal.h"
#include "abbe_model.h"

/* stdin: n, then per sample dt_ms, the f32 inputs, the q inputs; stdout: per sample the
 * channels after the f32 update (um as printed) and after the q update (nm). */
int main(void)
{
    static abbe_thermal_model_t th;
    static abbe_thermal_state_t sf, sq;
    abbe_model_t m;
    int st = (int)abbe_thermal_load(&m, &th, abbe_model_blob, abbe_model_blob_size);
    unsigned n_in = abbe_thermal_n_inputs(&th), n_ch = abbe_thermal_n_channels(&th), n, k, c;
    printf("%d %u %u %u\n", st, n_in, n_ch, (unsigned)(abbe_model_crc(&m) == ABBE_MODEL_BLOB_CRC32));
    if (st != 0 || abbe_thermal_init_f32(&sf, &th, 0.001f) != ABBE_OK ||
        abbe_thermal_init_q(&sq, &th, 1000u) != ABBE_OK || scanf("%u", &n) != 1) {
        return 1;
    }
    for (unsigned i = 0; i < n; i++) {
        unsigned dt_ms;
        float x[ABBE_THERMAL_MAX_INPUTS];
        long xl;
        int32_t xm[ABBE_THERMAL_MAX_INPUTS];
        if (scanf("%u", &dt_ms) != 1) return 1;
        for (k = 0; k < n_in; k++) {
            if (scanf("%f", &x[k]) != 1) return 1;
        }
        for (k = 0; k < n_in; k++) {
            if (scanf("%ld", &xl) != 1) return 1;
            xm[k] = (int32_t)xl;
        }
        if (abbe_thermal_update_f32(&sf, x, 0x1FFFFu, (float)dt_ms * 0.001f) != ABBE_OK ||
            abbe_thermal_update_q(&sq, xm, 0x1FFFFu, dt_ms) != ABBE_OK) {
            return 1;
        }
        float yf[ABBE_THERMAL_MAX_CHANNELS];
        int32_t yq[ABBE_THERMAL_MAX_CHANNELS];
        abbe_thermal_channels_f32(&sf, yf);
        abbe_thermal_channels_q(&sq, yq);
        for (c = 0; c < n_ch; c++) printf("%.9g ", (double)yf[c]);
        for (c = 0; c < n_ch; c++) printf("%ld ", (long)yq[c]);
        printf("%u\n", (unsigned)(abbe_thermal_flags(&sf) | abbe_thermal_flags(&sq)));
    }
    return 0;
}
"""


def _table(tmp_path: Path) -> tuple[Path, bytes]:
    model = from_dict(json.loads((REPO / "examples/spindle_thermal/thermal.json").read_text()))
    inputs = list(model.inputs)
    inputs[4] = replace(inputs[4], stuck_s=600.0, stuck_resolution=0.005)  # 10 min: the record moves
    model = replace(model, inputs=tuple(inputs))
    blob = write_thermal_blob((REPO / "examples/paper_table/model.bin").read_bytes(), model)
    path = tmp_path / "thermal13.bin"
    path.write_bytes(blob)
    return path, blob


def _record(model) -> tuple[np.ndarray, np.ndarray]:
    """dt (ms, first 0) and inputs (N, 17): temperatures rising from their references with
    a ripple, the speed in 30-min steps; samples 5-60 s apart."""
    rng = np.random.default_rng(35)
    dt = rng.choice([5000, 15000, 15000, 30000, 60000], size=N)
    dt[0] = 0
    t = np.cumsum(dt) / 1000.0
    x = np.empty((N, len(model.inputs)))
    for k, inp in enumerate(model.inputs):
        if inp.kind == SPEED:
            x[:, k] = np.where((t // 1800) % 2 == 1, 1250.0 * (1 + (t // 3600) % 4), 0.0)
        else:
            amp, tau = rng.uniform(1, 8), rng.uniform(900, 5000)
            x[:, k] = inp.reference + amp * (1 - np.exp(-t / tau)) + 0.3 * np.sin(t / 600 + k)
    return dt, x


def test_cgen_thermal_table_runs_in_the_library(tmp_path: Path, capsys) -> None:
    path, blob = _table(tmp_path)
    gen = tmp_path / "gen"
    assert cli(["table", "cgen", str(path), "-o", str(gen)]) == 0
    capsys.readouterr()
    ht, ct = (gen / "abbe_model.h").read_text(), (gen / "abbe_model.c").read_text()
    assert "ABBE_TABLE_FORMAT_MINOR < 0" in ht and "ABBE_THERMAL_FORMAT_MINOR != 3" in ht
    assert "abbe_thermal_load()" in ct and "17 inputs, 5 channels" in ct
    assert "stuck after 600 s within 0.005" in ct
    hexes = ct.split("= {", 1)[1].split("};", 1)[0].replace(",", " ").split()
    assert bytes(int(v, 16) for v in hexes) == blob

    inc = REPO / "lib" / "include"
    (tmp_path / "main.c").write_text(MAIN_C)
    exe = tmp_path / "run"
    lib_sources = sorted(str(p) for p in (REPO / "lib" / "src").glob("*.c"))
    subprocess.run(["cc", "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror", f"-I{inc}",
                    f"-I{gen}", str(tmp_path / "main.c"), str(gen / "abbe_model.c"), *lib_sources,
                    "-o", str(exe)], check=True, capture_output=True)

    _, model_q = read_thermal_blob(blob)  # the model as the table holds it
    dt, x = _record(model_q)
    speed = np.array([i.kind == SPEED for i in model_q.inputs])
    x32 = x.astype(np.float32)
    xm = np.where(speed, np.rint(x), np.rint(x * 1000.0)).astype(np.int64)
    lines = [str(N)] + [" ".join([str(int(dt[i]))] + [f"{v:.9g}" for v in x32[i]]
                                 + [str(v) for v in xm[i]]) for i in range(N)]
    run = subprocess.run([str(exe)], input="\n".join(lines) + "\n", capture_output=True, text=True,
                         check=True)
    out = run.stdout.strip().splitlines()
    assert out[0].split() == ["0", "17", "5", "1"]  # ABBE_OK, the shape, the CRC macro
    rows = np.array([[float(v) for v in ln.split()] for ln in out[1:]])
    assert rows.shape == (N, 11)
    # no fault flag (ABBE_THERMAL_F_FAULTS): the stuck check sees a moving input
    assert np.all(rows[:, 10].astype(int) & 0x8F == 0)

    t = np.cumsum(dt) / 1000.0
    ref_f = evaluate(model_q, t, x32.astype(np.float64)) * 1000.0      # nm / nrad
    ref_q = evaluate(model_q, t, np.where(speed, xm, xm / 1000.0)) * 1000.0
    got_f, got_q = rows[:, :5] * 1000.0, rows[:, 5:10]
    assert np.abs(ref_q).max() > 5000.0  # the channels move by micrometres
    # the golden vectors' tolerances (tests/golden/golden_thermal.h)
    err_f = np.abs(got_f - ref_f) - 2e-5 * np.abs(ref_f)
    err_q = np.abs(got_q - ref_q) - 1e-6 * np.abs(ref_q)
    print(f"cgen 1.3: largest |C - reference| f32 {np.abs(got_f - ref_f).max():.2f} nm, "
          f"q {np.abs(got_q - ref_q).max():.2f} nm over {N} samples")
    assert err_f.max() <= 20.0 and err_q.max() <= 4.0


def test_cgen_thermal_guard_and_refusal(tmp_path: Path, capsys) -> None:
    path, blob = _table(tmp_path)
    gen = tmp_path / "gen"
    assert cli(["table", "cgen", str(path), "-o", str(gen)]) == 0
    # python -m abbe.formats.c_source writes the same files
    from abbe.formats.c_source import main as c_source_main
    assert c_source_main(["--c", str(path), "-o", str(tmp_path / "module")]) == 0
    assert (tmp_path / "module" / "abbe_model.c").read_bytes() == (gen / "abbe_model.c").read_bytes()
    capsys.readouterr()
    # a library whose thermal block is another minor refuses the generated file at build time
    fake = tmp_path / "fake" / "abbe"
    fake.mkdir(parents=True)
    (fake / "version.h").write_text("#define ABBE_TABLE_FORMAT_MAJOR 1\n#define ABBE_TABLE_FORMAT_MINOR 1\n")
    (fake / "thermal.h").write_text("#define ABBE_THERMAL_FORMAT_MINOR 2\n")
    r = subprocess.run(["cc", "-std=c99", "-fsyntax-only", f"-I{tmp_path / 'fake'}", f"-I{gen}",
                        str(gen / "abbe_model.c")], capture_output=True, text=True)
    assert r.returncode != 0 and "thermal block): regenerate it" in r.stderr
    # a broken thermal block: exit 2, the file and the field named, nothing written
    bad = bytearray(blob)
    off = int.from_bytes(bad[60:64], "little")
    bad[off + 16] = 7  # input 0's kind
    import zlib
    bad[-4:] = (zlib.crc32(bytes(bad[:-4])) & 0xFFFFFFFF).to_bytes(4, "little")
    bad_path = tmp_path / "bad13.bin"
    bad_path.write_bytes(bytes(bad))
    assert cli(["table", "cgen", str(bad_path), "-o", str(tmp_path / "badgen")]) == 2
    err = capsys.readouterr().err
    assert str(bad_path) in err and "ABBE_E_FLAGS" in err
    assert not (tmp_path / "badgen" / "abbe_model.c").exists()
