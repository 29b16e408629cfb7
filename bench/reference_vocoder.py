#!/usr/bin/env python3
"""The noise-excited channel vocoder of `avsi vocode` in numpy/scipy: what a
lab would otherwise write (Shannon et al. 1995, the settings of
vocoder/include/avsi/vocoder/vocoder.h's defaults).

    python3 bench/reference_vocoder.py in.wav out.wav [--bands 3] [--seed 1]

Bands with Greenwood (1990) spacing between --low-hz and --high-hz; each a
Butterworth band-pass of prototype order 4 (scipy's butter(4, band) is the
same 8-pole, 4-section design avsi uses), run causally with sosfilt;
half-wave rectification and a 4th-order 160 Hz Butterworth envelope low-pass;
white noise carriers (numpy's generator, so the noise differs from avsi's
xoshiro streams); the modulated carrier back through its band; each band's
RMS set to its analysis band's RMS, the sum's RMS to the input's; scaled
down as a whole if it would clip. 16-bit WAV in and out (scipy.io.wavfile).

Used by bench/bench_whole_process.sh as the baseline avsi is timed against;
`--check AVSI_OUTPUT.wav` compares the two outputs' band levels instead of
writing (the carriers differ, so the samples do not; the overall level can
differ by the anti-clipping scale, the same for every band).
"""
import argparse
import sys

import numpy as np
from scipy import signal
from scipy.io import wavfile


def greenwood_hz(x):
    return 165.4 * (10.0 ** (2.1 * x) - 0.88)


def greenwood_position(f_hz):
    return np.log10(f_hz / 165.4 + 0.88) / 2.1


def band_edges(bands, low_hz, high_hz):
    x0, x1 = greenwood_position(low_hz), greenwood_position(high_hz)
    edges = greenwood_hz(x0 + (x1 - x0) * np.arange(bands + 1) / bands)
    edges[0], edges[-1] = low_hz, high_hz
    return edges


def read_wav(path):
    rate, data = wavfile.read(path)
    if data.dtype == np.int16:
        x = data.astype(np.float64) / 32768.0
    elif data.dtype == np.int32:
        x = data.astype(np.float64) / 2147483648.0
    else:
        x = data.astype(np.float64)
    return rate, x


def vocode(x, rate, bands=3, low_hz=100.0, high_hz=5000.0, order=4, envelope_cutoff_hz=160.0,
           envelope_order=4, seed=1):
    edges = band_edges(bands, low_hz, high_hz)
    envelope_sos = signal.butter(envelope_order, envelope_cutoff_hz, btype="lowpass", fs=rate, output="sos")
    rng = np.random.default_rng(seed)
    out = np.zeros_like(x)
    for b in range(bands):
        sos = signal.butter(order, [edges[b], edges[b + 1]], btype="bandpass", fs=rate, output="sos")
        analysis = signal.sosfilt(sos, x)
        envelope = signal.sosfilt(envelope_sos, np.maximum(analysis, 0.0))
        carrier = rng.uniform(-1.0, 1.0, size=x.shape[0])
        band = signal.sosfilt(sos, np.maximum(envelope, 0.0) * carrier)
        rms_in = np.sqrt(np.mean(analysis ** 2))
        rms_out = np.sqrt(np.mean(band ** 2))
        if rms_out > 0:
            band *= rms_in / rms_out
        out += band
    rms_x, rms_y = np.sqrt(np.mean(x ** 2)), np.sqrt(np.mean(out ** 2))
    if rms_y > 0:
        out *= rms_x / rms_y
    peak = np.max(np.abs(out)) if out.size else 0.0
    if peak > 1.0:
        out *= 0.999 / peak
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--bands", type=int, default=3)
    ap.add_argument("--low-hz", type=float, default=100.0)
    ap.add_argument("--high-hz", type=float, default=5000.0)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--check", metavar="AVSI_OUTPUT",
                    help="instead of writing, compare per-band RMS with avsi's output (exit 1 if the band "
                         "differences spread over more than 0.5 dB)")
    a = ap.parse_args()
    rate, x = read_wav(a.input)
    if x.ndim != 1:
        sys.exit("reference_vocoder.py: mono input only")
    y = vocode(x, rate, a.bands, a.low_hz, a.high_hz, seed=a.seed)
    if a.check:
        _, z = read_wav(a.check)
        edges = band_edges(a.bands, a.low_hz, a.high_hz)
        diffs = []
        for b in range(a.bands):
            sos = signal.butter(4, [edges[b], edges[b + 1]], btype="bandpass", fs=rate, output="sos")
            ours, theirs = signal.sosfilt(sos, y), signal.sosfilt(sos, z)
            diffs.append(20 * np.log10(np.sqrt(np.mean(ours ** 2)) / np.sqrt(np.mean(theirs ** 2))))
            print(f"band {b} ({edges[b]:.1f}-{edges[b + 1]:.1f} Hz): scipy - avsi = {diffs[-1]:+.3f} dB")
        # A common offset comes from the anti-clipping scale (the two noises
        # peak differently); the spectral shape is the spread.
        spread = max(diffs) - min(diffs)
        print(f"spread across bands: {spread:.3f} dB (at most 0.5 dB: the same band levels)")
        sys.exit(0 if spread <= 0.5 else 1)
    pcm = np.clip(np.round(y * 32767.0), -32768, 32767).astype(np.int16)
    wavfile.write(a.output, rate, pcm)


if __name__ == "__main__":
    main()
