#!/usr/bin/env python3
"""`avsi vocode`'s cochlear-implant simulation held to the numpy/scipy one
(bench/reference_vocoder.py: ci_vocode, written from the equations of
vocoder/include/avsi/vocoder/ci_simulation.h).

    python3 tests/vocoder/ci_reference_test.py build/cli/avsi

For each case (pulse-train carriers interleaved and simultaneous, Poisson
pulses, sine carriers 4 mm shifted, and a pulse-train vocoder with current
spread, a shift, synthesis filters of their own order and 4-of-8 selection)
both vocode the same 16-bit speech-like input; then, in every carrier band:
  - the band's output level (RMS through the carrier band's filter),
  - the band's envelope (|analytic signal| low-passed at 50 Hz; its RMS and
    the RMS of the difference),
  - the carrier spectrum (Welch PSD over the band, the bins within 30 dB of
    its peak: below, the two 16-bit outputs' own rounding noise shows)
must agree within 0.1 dB, and the n-of-m selection log must name the same
bands. Exit 0 when every case passes, 1 otherwise (each difference printed).
"""
import os
import subprocess
import sys
import tempfile

import numpy as np
from scipy import signal
from scipy.io import wavfile

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "bench"))
import reference_vocoder as ref  # noqa: E402

RATE = 22050
TOLERANCE_DB = 0.1


def speech_like(seconds=2.0, seed=5):
    """A harmonic series (F0 gliding 100–140 Hz) through three moving resonances, 4 Hz syllables."""
    t = np.arange(int(RATE * seconds)) / RATE
    f0 = 120.0 + 20.0 * np.sin(2 * np.pi * 0.7 * t)
    phase = 2 * np.pi * np.cumsum(f0) / RATE
    formants = [500.0 + 200.0 * np.sin(2 * np.pi * 1.3 * t), 1500.0 + 400.0 * np.sin(2 * np.pi * 0.9 * t),
                2500.0 + 0 * t]
    x = np.zeros_like(t)
    for k in range(1, 45):
        gain = sum(1.0 / (1.0 + ((k * f0 - f) / 120.0) ** 2) for f in formants)
        x += gain / k * np.sin(k * phase) * (k * f0 < 5000)
    syllable = 0.5 * (1.0 - np.cos(2 * np.pi * 4.0 * t))
    x = 0.1 * syllable * x + 0.002 * np.random.default_rng(seed).normal(size=t.size)
    return np.round(np.clip(x, -1, 1) * 32767) / 32768.0


def pcm16(y):
    return np.clip(np.round(y * 32767.0), -32768, 32767).astype(np.int16)


CASES = [
    ("pulse-train interleaved", {"carrier": "pulse-train"}, "--carrier pulse-train"),
    ("pulse-train simultaneous", {"carrier": "pulse-train", "pulse_phase": "simultaneous"},
     "--carrier pulse-train --pulse-phase simultaneous"),
    ("poisson", {"carrier": "poisson", "pulse_rate": 150.0, "seed": 7},
     "--carrier poisson --pulse-rate 150 --seed 7"),
    ("sine, 4 mm shift", {"carrier": "sine", "shift_mm": 4.0}, "--carrier sine --insertion-shift-mm 4"),
    ("pulse-train, spread 8 dB/oct, 3 mm, order 6, 4 of 8",
     {"carrier": "pulse-train", "spread": "db-per-octave", "spread_slope_db": 8.0, "shift_mm": 3.0,
      "synthesis_order": 6, "n_of_m": 4, "frame_rate": 250.0},
     "--carrier pulse-train --current-spread db-per-octave --spread-slope-db 8 --insertion-shift-mm 3 "
     "--synthesis-order 6 --n-of-m 4 --selection-rate 250"),
]


def envelope(y, sos):
    return signal.sosfilt(sos, np.abs(signal.hilbert(y)))


def db(a, b):
    return 20 * np.log10(a / b)


def compare_bands(ours, theirs, settings):
    """Every per-band difference in dB: level, envelope and spectrum."""
    edges = ref.band_edges(8, 100.0, 5000.0)
    carrier_edges = ref.shifted_edges(edges, settings.get("shift_mm", 0.0)) if settings.get("shift_mm") else edges
    smooth = signal.butter(4, 50.0, btype="lowpass", fs=RATE, output="sos")
    worst = []
    for b in range(8):
        sos = signal.butter(4, [carrier_edges[b], carrier_edges[b + 1]], btype="bandpass", fs=RATE, output="sos")
        a, n = signal.sosfilt(sos, ours), signal.sosfilt(sos, theirs)
        level = db(np.sqrt(np.mean(a ** 2)), np.sqrt(np.mean(n ** 2)))
        ea, en = envelope(a, smooth), envelope(n, smooth)
        env_level = db(np.sqrt(np.mean(ea ** 2)), np.sqrt(np.mean(en ** 2)))
        env_shape = db(1.0 + np.sqrt(np.mean((ea - en) ** 2)) / np.sqrt(np.mean(en ** 2)), 1.0)
        f, pa = signal.welch(ours, RATE, nperseg=4096)
        _, pn = signal.welch(theirs, RATE, nperseg=4096)
        inside = (f >= carrier_edges[b]) & (f <= carrier_edges[b + 1])
        strong = inside & (pn >= pn[inside].max() * 1e-3)
        spectrum = np.max(np.abs(10 * np.log10(pa[strong] / pn[strong])))
        worst.append((b, level, env_level, env_shape, spectrum))
    return worst


def run_case(avsi, folder, x, name, settings, options):
    wav_in, wav_out, log = (os.path.join(folder, f) for f in ("in.wav", "out.wav", "selection.csv"))
    wavfile.write(wav_in, RATE, pcm16(x))
    command = f"{avsi} vocode {wav_in} {wav_out} --bands 8 {options}"
    if settings.get("n_of_m"):
        command += f" --selection-log {log}"
    subprocess.run(command.split(), check=True, capture_output=True)
    ours = wavfile.read(wav_out)[1].astype(np.float64) / 32768.0
    y, _, selection = ref.ci_vocode(x, RATE, bands=8, keep_bands=True, **settings)
    theirs = pcm16(y).astype(np.float64) / 32768.0
    ok = True
    print(f"{name}:")
    for b, level, env_level, env_shape, spectrum in compare_bands(ours, theirs, settings):
        fine = max(abs(level), abs(env_level), env_shape, spectrum) <= TOLERANCE_DB
        ok &= fine
        print(f"  band {b}: level {level:+.4f} dB, envelope {env_level:+.4f} dB (difference {env_shape:.4f} dB), "
              f"spectrum within {spectrum:.4f} dB{'' if fine else '  <-- over 0.1 dB'}")
    if selection is not None:
        rows = [line.split(",") for line in open(log).read().splitlines()[1:]]
        kept = np.zeros_like(selection)
        for frame, _, bands in rows:
            kept[int(frame), [int(b) for b in bands.split()]] = True
        same = np.all(kept == selection, axis=1).mean()
        ok &= kept.shape == selection.shape and same >= 0.99
        print(f"  selection: {len(rows)} frames, the same bands in {100 * same:.2f} % of them")
    return ok


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    x = speech_like()
    ok = True
    with tempfile.TemporaryDirectory() as folder:
        for name, settings, options in CASES:
            ok &= run_case(sys.argv[1], folder, x, name, settings, options)
    print("all within 0.1 dB" if ok else "FAILED")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
