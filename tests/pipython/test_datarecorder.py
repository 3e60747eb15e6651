"""PIPython's own data recorder tools against `host-sim serve`: a 1 mm move recorded and read back.

Unmodified PIPython (`pip install pipython`): `datarectools.Datarecorder` learns the servo update
time from parameter 0x0E000200 (`SPA?`), the table depth from parameter 0x16000201 (the first it
asks for; `HDR?`'s additional information says the same), the record and trigger options from
`HDR?`; the number of tables comes from `TNR?`. The test records
all eight tables (commanded, actual position, position error, drive amplitude, drive frequency,
preload, controller state, actual position again) around `MOV 1 1.0`, reads every table back
with `DRR?` (PI's GCS array format, parsed by PIPython's `qDRR`) and checks the points below;
then it records the move back with `Datarecorder`'s defaults (table 1, actual position,
trigger 2: the next command). Checks of the first recording:

- the header: DIM, NDATA, SAMPLE_TIME = RTR x servo update time, the column names;
- the recorded actual position at the end equals `POS?` (to one encoder count);
- the recorded settle time (first point from which the position stays within +-1 encoder count,
  50 nm, of the target) agrees with `host-sim move --to-um 1000 --json` within one record period.
  The move starts as `host-sim move` does: at rest at 0 (`RON 1 0`, `POS 1 0`), servo just on.
  Record period: RTR 50 (5 ms, 5.1 s of 1024 points). The virtual controller is paced by the wall
  clock, so its settle time varies by a few ms from run to run (0.424-0.428 s against the 0.425 s
  of `host-sim move`, observed Nov 2026): a shorter period would test that spread, not the recorder.

Run: python3 tests/pipython/test_datarecorder.py [path/to/host-sim]   (exit code 0 = pass)
"""
import json
import os
import subprocess
import sys
import time

from pipython import GCSDevice, datarectools
from pipython.pidevice.interfaces.pisocket import PISocket

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, HERE)
from test_pipython import quiet_double_close, start_server, stop_server  # noqa: E402

COUNT_MM = 50e-6  # one encoder count
TARGET_MM = 1.0
RATE = 50  # record rate: one point every 50 control ticks (5 ms)
OPTIONS = [1, 2, 3, 256, 257, 258, 259, 2]


def settle_index(positions, target):
    """First index from which every point stays within one count of the target, or None."""
    idx = None
    for i, p in enumerate(positions):
        if abs(p - target) <= COUNT_MM + 1e-9:
            if idx is None:
                idx = i
        else:
            idx = None
    return idx


def main():
    sys.unraisablehook = quiet_double_close
    binary = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "target", "release", "host-sim")
    t0 = time.monotonic()
    ref = json.loads(subprocess.run([binary, "move", "--to-um", "1000", "--json"],
                                    check=True, capture_output=True, text=True).stdout)
    print(f"host-sim move --to-um 1000: settle {ref['settle_time_s']} s")
    proc, port = start_server(binary)
    try:
        with GCSDevice(gateway=PISocket(host="127.0.0.1", port=port)) as pidevice:
            ntables = pidevice.qTNR()
            assert ntables == len(OPTIONS), ntables
            drec = datarectools.Datarecorder(pidevice)
            assert abs(drec.servotime - 1e-4) < 1e-12, drec.servotime  # SPA? 1 0x0E000200
            depth = drec.maxnumvalues  # SPA? 1 0x16000201
            info = datarectools.get_hdr_options(pidevice, return_additional_info=True)[2]
            assert f"{depth} datapoints per table" in info, info
            assert set(OPTIONS) <= set(drec.recopts), drec.recopts
            assert {0, 1, 4, 6} <= set(drec.trigopts), drec.trigopts
            print(f"{ntables} tables of {depth} points, servo update time {drec.servotime} s, "
                  f"record options {drec.recopts}, trigger options {drec.trigopts}")

            # At rest at 0, as `host-sim move` starts.
            pidevice.RON("1", False)
            pidevice.POS("1", 0.0)
            drec.numvalues = depth
            drec.samplerate = RATE  # RTR
            drec.options = OPTIONS  # DRC 1..8
            drec.sources = "1"
            drec.trigsources = datarectools.TriggerSources.POS_CHANGING_WITH_RESET_6  # DRT 0 6 0
            drec.arm()
            assert pidevice.qRTR() == RATE
            assert pidevice.qDRC() == {t: ["1", o] for t, o in enumerate(OPTIONS, 1)}, pidevice.qDRC()
            assert all(v == [6, "0"] for v in pidevice.qDRT().values()), pidevice.qDRT()
            pidevice.SVO("1", True)
            pidevice.MOV("1", TARGET_MM)
            header, data = drec.getdata(timeout=30)  # DRL? until full, then DRR? 1 <depth> 1..8
            pos = pidevice.qPOS("1")["1"]
            drl = pidevice.qDRL()
            assert all(n == depth for n in drl.values()), drl

            # PIPython's defaults throughout: table 1 records the actual position, trigger 2 (the
            # next command, here the move back), sent without ERR? after it as PIPython does.
            back = datarectools.Datarecorder(pidevice)
            back.arm()
            pidevice.MOV("1", 0.0)
            _, (back_actual,) = back.getdata(timeout=30)
            assert pidevice.qDRT(1)[1] == [2, "0"] and pidevice.qERR() == 0
            assert len(back_actual) == depth and abs(back_actual[0] - TARGET_MM) <= COUNT_MM + 1e-9
            assert abs(back_actual[-1] - pidevice.qPOS("1")["1"]) <= COUNT_MM + 1e-9, back_actual[-1]
            print(f"default trigger (2): {depth} points from {back_actual[0]} to {back_actual[-1]} mm")
    finally:
        stop_server(proc)

    sample_s = RATE * 1e-4
    print("header:", dict(header))
    assert header["DIM"] == len(OPTIONS) and header["NDATA"] == depth, header
    assert abs(header["SAMPLE_TIME"] - sample_s) < 1e-12, header
    assert header["NAME1"].startswith("Actual position") and header["NAME6"].startswith("Controller state")
    assert len(data) == len(OPTIONS) and all(len(col) == depth for col in data), [len(c) for c in data]
    commanded, actual, error, amplitude, frequency, preload, state, actual2 = data
    # Every table read back, consistent with the others.
    assert actual == actual2
    assert all(abs(e - (c - a)) < 1e-9 for c, a, e in zip(commanded, actual, error))
    assert commanded[0] == 0.0 and commanded[-1] == TARGET_MM
    assert state[0] == 1 and state[-1] == 2, (state[0], state[-1])  # moving, then holding
    assert max(amplitude) > 10.0 and all(f > 0 for f in frequency), (max(amplitude), frequency[:3])
    assert all(14.0 < f < 18.0 for f in preload), (min(preload), max(preload))

    print(f"POS? {pos:.6f} mm, last recorded {actual[-1]:.6f} mm")
    assert abs(actual[-1] - pos) <= COUNT_MM + 1e-9, (actual[-1], pos)
    i = settle_index(actual, TARGET_MM)
    assert i is not None, "never settled within the recording"
    settle = i * sample_s
    print(f"recorded settle {settle:.4f} s (point {i + 1}), host-sim move {ref['settle_time_s']} s, "
          f"record period {sample_s} s")
    assert abs(settle - ref["settle_time_s"]) <= sample_s + 1e-9, (settle, ref["settle_time_s"])
    print(f"PIPython data recorder test passed in {time.monotonic() - t0:.1f} s")


if __name__ == "__main__":
    main()
