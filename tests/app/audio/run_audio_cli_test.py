#!/usr/bin/python3
"""`volume-haptics run --audio` end to end on the built-in drilling scene (resources/scenes/
sphere-drill.json): the burr runs free above the sphere for a second, then the device presses
into it; the WAV's rate and length must match the run, and its fundamental, measured here by a
plain periodogram (numpy, Hann window, zero-padded), must be near flutes x rpm / 60 running free
and near the motor line at the trace's |F| while pushing. A scene without a drill, and a folder
that cannot be made, are refused before anything is loaded.

usage: run_audio_cli_test.py VOLUME_HAPTICS SOURCE_DIR WORK_DIR
"""
import json
import os
import shutil
import subprocess
import sys
import wave

import numpy as np

# vh::audio's default burr (BurrSoundModel) and the scene's drill: flutes, no-load speed [rpm],
# mu, stall torque [N*m], reference hardness [J/mm^3]; burr radius [m], hardness [J/mm^3].
FLUTES, RPM, MU, STALL_NM, REFERENCE_HARDNESS = 6, 80000.0, 0.2, 0.01, 0.6
RADIUS, HARDNESS = 0.0025, 2.0


def fundamental_hz(x, fs):
    """The largest periodogram peak between 100 Hz and 20 kHz, to 0.1 Hz (zero-padded DFT)."""
    n = len(x)
    spectrum = np.abs(np.fft.rfft(x * np.hanning(n), 16 * n)) ** 2
    freqs = np.fft.rfftfreq(16 * n, 1.0 / fs)
    band = (freqs > 100.0) & (freqs < 20000.0)
    return float(freqs[band][np.argmax(spectrum[band])])


def main():
    exe, source, work = sys.argv[1], sys.argv[2], sys.argv[3]
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    trajectory = os.path.join(work, "press.csv")
    # Above the sphere (top at z = 20 mm, burr radius 2.5 mm) until 1 s, down to 12.5 mm by 2 s,
    # held there until 3 s.
    with open(trajectory, "w") as f:
        for t, z in [(0.0, 0.030), (1.0, 0.030), (2.0, 0.0125), (3.0, 0.0125)]:
            f.write(f"{t},0,0,{z},1,0,0,0\n")
    wav_path = os.path.join(work, "new-folder", "session.wav")  # the folder is created by run
    report_path = os.path.join(work, "report.json")
    trace_path = os.path.join(work, "trace.csv")
    scene = os.path.join(source, "resources", "scenes", "sphere-drill.json")
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}
    done = subprocess.run([exe, "run", "--scene", scene, "--trajectory", trajectory, "--audio", wav_path,
                           "--report", report_path, "--trace", trace_path, "--verify-step", "0", "--no-lag-reference"],
                          capture_output=True, text=True, env=env, timeout=900)
    print(done.stdout, done.stderr)
    assert done.returncode == 0, f"run failed: {done.returncode}"
    assert "sound written to" in done.stdout
    report = json.load(open(report_path))
    assert report["removed_mm3"] > 1.0, "the burr must have cut"

    with wave.open(wav_path) as w:
        fs, channels, width, frames = w.getframerate(), w.getnchannels(), w.getsampwidth(), w.getnframes()
        x = np.frombuffer(w.readframes(frames), dtype="<i2").astype(np.float64) / 32768.0
    duration = frames / fs
    run_s = report["ticks"] / report["servo_rate_Hz"]
    print(f"WAV: {fs} Hz, {channels} channel(s), {8 * width} bit, {frames} frames = {duration:.4f} s; "
          f"run {report['ticks']} ticks = {run_s:.4f} s")
    assert (fs, channels, width) == (48000, 1, 2)
    assert abs(duration - run_s) <= 1.0 / fs + 1e-9, "the sound lasts as long as the run"
    assert np.max(np.abs(x)) <= 1.0 and np.max(np.abs(x)) > 0.05

    free = fundamental_hz(x[int(0.3 * fs):int(0.9 * fs)], fs)
    expected = FLUTES * RPM / 60.0
    print(f"fundamental free running {free:.1f} Hz (flutes x rpm / 60 = {expected:.1f} Hz)")
    assert abs(free - expected) <= 0.02 * expected

    # While pushing: lower, and near the motor line at the window's mean |F| (the trace's).
    trace = np.genfromtxt(trace_path, delimiter=",", names=True, usecols=("t_s", "fx_N", "fy_N", "fz_N"))
    force = np.sqrt(trace["fx_N"] ** 2 + trace["fy_N"] ** 2 + trace["fz_N"] ** 2)
    pushing = []
    for a, b in [(1.6, 1.8), (2.0, 2.2), (2.4, 2.6), (2.8, 3.0)]:
        f = fundamental_hz(x[int(a * fs):int(b * fs)], fs)
        mean_force = float(np.mean(force[(trace["t_s"] >= a) & (trace["t_s"] < b)]))
        line = expected * max(1.0 - MU * mean_force * RADIUS * HARDNESS / REFERENCE_HARDNESS / STALL_NM, 0.1)
        print(f"pushing {a}-{b} s: mean |F| {mean_force:.2f} N, fundamental {f:.1f} Hz (motor line {line:.1f} Hz)")
        assert f < 0.9 * free, "the push must lower the pitch"
        assert abs(f - line) <= 0.1 * line, "the pitch follows the motor line"
        pushing.append(f)

    # Without a drill: refused before loading, nothing written.
    refused_wav = os.path.join(work, "refused.wav")
    no_drill = subprocess.run([exe, "run", "--scene", os.path.join(source, "resources", "scenes", "sphere-probe.json"),
                               "--trajectory", trajectory, "--audio", refused_wav],
                              capture_output=True, text=True, env=env, timeout=360)
    print(no_drill.stderr)
    assert no_drill.returncode == 1
    assert "--audio needs a drilling scene" in no_drill.stderr and "has no \"drill\" section" in no_drill.stderr
    assert not os.path.exists(refused_wav)
    # A drill that is off: a headless run never starts it.
    off_scene = os.path.join(work, "drill-off.json")
    with open(scene) as f:
        spec = json.load(f)
    spec["drill"]["on"] = False
    with open(off_scene, "w") as f:
        json.dump(spec, f)
    off = subprocess.run([exe, "run", "--scene", off_scene, "--trajectory", trajectory, "--audio", refused_wav],
                         capture_output=True, text=True, env=env, timeout=360)
    print(off.stderr)
    assert off.returncode == 1 and "--audio needs a drilling scene" in off.stderr and "is off" in off.stderr
    assert not os.path.exists(refused_wav)
    # A folder that cannot be made (a file in the way): refused before the scene is read.
    blocker = os.path.join(work, "blocker")
    open(blocker, "w").write("a file")
    no_folder = subprocess.run([exe, "run", "--scene", "/no/such/scene.json", "--trajectory", trajectory,
                                "--audio", os.path.join(blocker, "sub", "x.wav")],
                               capture_output=True, text=True, env=env, timeout=360)
    print(no_folder.stderr)
    assert no_folder.returncode == 1
    assert "--audio" in no_folder.stderr and "cannot create the folder" in no_folder.stderr
    assert "scene file not found" not in no_folder.stderr
    print("run --audio: all checks passed")


if __name__ == "__main__":
    main()
