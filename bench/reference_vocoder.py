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

`ci_vocode` is the cochlear-implant simulation of `avsi vocode` (the steps
of vocoder/include/avsi/vocoder/ci_simulation.h) written again from those
equations: pulse-train and Poisson pulse carriers (each sample holding its
overlap with a rectangular pulse), carrier bands shifted along Greenwood's
map, synthesis filters of their own order, n-of-m selection per frame and
current spread in dB/octave or dB/mm. `Xoshiro` is avsi's seeded generator
(core/src/rng.cpp: xoshiro256** seeded by SplitMix64, streams derived by
FNV-1a), so the Poisson pulse times are avsi's too.
tests/vocoder/ci_reference_test.py holds avsi to it.
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


# ------------------------------------------------------------- CI simulation

MASK64 = (1 << 64) - 1


def _splitmix64(x):
    x = (x + 0x9E3779B97F4A7C15) & MASK64
    z = x
    z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK64
    z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK64
    return x, z ^ (z >> 31)


def _rotl(x, k):
    return ((x << k) | (x >> (64 - k))) & MASK64


class Xoshiro:
    """xoshiro256** seeded through SplitMix64, as avsi::Rng."""

    def __init__(self, seed):
        self.state = []
        x = seed & MASK64
        for _ in range(4):
            x, z = _splitmix64(x)
            self.state.append(z)

    @staticmethod
    def derived(seed, name):
        h = 0xcbf29ce484222325
        for c in name.encode():
            h ^= c
            h = (h * 0x100000001b3) & MASK64
        _, z = _splitmix64(seed ^ h)
        return Xoshiro(z)

    def next_u64(self):
        s = self.state
        result = (_rotl((s[1] * 5) & MASK64, 7) * 9) & MASK64
        t = (s[1] << 17) & MASK64
        s[2] ^= s[0]
        s[3] ^= s[1]
        s[1] ^= s[2]
        s[0] ^= s[3]
        s[2] ^= t
        s[3] = _rotl(s[3], 45)
        return result

    def uniform(self):
        return (self.next_u64() >> 11) * 2.0 ** -53


def shifted_edges(edges, shift_mm):
    return greenwood_hz(greenwood_position(np.asarray(edges)) + shift_mm / 35.0)


def add_pulse(c, start, width):
    end = start + width
    n = int(max(0.0, np.floor(start)))
    while n < c.size and n < end:
        c[n] += max(0.0, min(end, n + 1.0) - max(start, float(n)))
        n += 1


def pulse_carrier(frames, rate, band, bands, pulse_rate, width_us, phase="interleaved", poisson=False, seed=1,
                  channel=0):
    c = np.zeros(frames)
    period = rate / pulse_rate
    width = width_us * 1e-6 * rate
    if poisson:
        stream = Xoshiro.derived(seed, f"channel{channel}/band{band}/poisson")
        t = 0.0
        while True:
            t += -np.log(1.0 - stream.uniform()) * period
            if not t < frames:
                return c
            add_pulse(c, t, width)
    offset = band / bands if phase == "interleaved" else 0.0
    k = 0
    while (k + offset) * period < frames:
        add_pulse(c, (k + offset) * period, width)
        k += 1
    return c


def run_filter(sos, x, zero_phase):
    y = signal.sosfilt(sos, x)
    return signal.sosfilt(sos, y[::-1])[::-1] if zero_phase else y


def spread_weights(centres, mode, slope_db):
    centres = np.asarray(centres)
    if mode == "none":
        return np.eye(len(centres))
    if mode == "db-per-mm":
        x = greenwood_position(centres) * 35.0
        distance = np.abs(x[None, :] - x[:, None])
    else:
        distance = np.abs(np.log2(centres[None, :] / centres[:, None]))
    return 10.0 ** (-slope_db * distance / 20.0)


def select_n_of_m(analysis, n, rate, frame_rate):
    """The n bands of largest energy per frame f = floor(i * frame_rate / rate), ties to the lower band."""
    m, samples = analysis.shape
    frame_of = np.floor(np.arange(samples) * frame_rate / rate).astype(int)
    frames = frame_of[-1] + 1
    energy = np.zeros((frames, m))
    for b in range(m):
        np.add.at(energy[:, b], frame_of, analysis[b] ** 2)
    keep = np.zeros((frames, m), dtype=bool)
    for f in range(frames):
        order = sorted(range(m), key=lambda b: (-energy[f, b], b))
        keep[f, order[:n]] = True
    return keep, frame_of


def ci_vocode(x, rate, bands=8, low_hz=100.0, high_hz=5000.0, order=4, synthesis_order=0, envelope_cutoff_hz=160.0,
              envelope_order=4, carrier="pulse-train", pulse_rate=100.0, pulse_width_us=100.0,
              pulse_phase="interleaved", spread="none", spread_slope_db=8.0, shift_mm=0.0, n_of_m=0,
              frame_rate=250.0, zero_phase=False, seed=1, keep_bands=False):
    """The CI simulation's steps 1–9 (half-wave envelopes, re-filtered carriers, band and output RMS matched)."""
    edges = band_edges(bands, low_hz, high_hz)
    carrier_edges = shifted_edges(edges, shift_mm) if shift_mm else edges
    synthesis_order = synthesis_order or order
    lowpass = signal.butter(envelope_order, envelope_cutoff_hz, btype="lowpass", fs=rate, output="sos")
    analysis, envelopes, carriers, synth, own, gains = [], [], [], [], [], []
    for b in range(bands):
        sos = signal.butter(order, [edges[b], edges[b + 1]], btype="bandpass", fs=rate, output="sos")
        synth.append(signal.butter(synthesis_order, [carrier_edges[b], carrier_edges[b + 1]], btype="bandpass",
                                   fs=rate, output="sos"))
        a = run_filter(sos, x, zero_phase)
        envelopes.append(np.maximum(run_filter(lowpass, np.maximum(a, 0.0), zero_phase), 0.0))
        if carrier == "sine":
            centre = np.sqrt(carrier_edges[b] * carrier_edges[b + 1])
            carriers.append(np.sin(2 * np.pi * centre * np.arange(x.size) / rate))
        else:
            carriers.append(pulse_carrier(x.size, rate, b, bands, pulse_rate, pulse_width_us, pulse_phase,
                                          carrier == "poisson", seed))
        y = run_filter(synth[b], envelopes[b] * carriers[b], zero_phase)
        rms_a, rms_y = np.sqrt(np.mean(a ** 2)), np.sqrt(np.mean(y ** 2))
        own.append(rms_y)
        gains.append(rms_a / rms_y if rms_y > 0 else 1.0)
        analysis.append(a)
    centres = np.sqrt(carrier_edges[:-1] * carrier_edges[1:])
    w = spread_weights(centres, spread, spread_slope_db)
    ratio = np.eye(bands)
    for b in range(bands):
        for k in range(bands):
            if b != k and w[b, k] >= 1e-6:
                level = np.sqrt(np.mean(run_filter(synth[k], envelopes[b] * carriers[k], zero_phase) ** 2))
                ratio[b, k] = own[b] / level if level > 0 else 0.0
    selection = None
    if n_of_m:
        keep, frame_of = select_n_of_m(np.array(analysis), n_of_m, rate, frame_rate)
        selection = keep
        for b in range(bands):
            envelopes[b] = envelopes[b] * keep[frame_of, b]
    out = np.zeros_like(x)
    band_outputs = []
    for k in range(bands):
        mixed = sum(w[b, k] * gains[b] * ratio[b, k] * envelopes[b] for b in range(bands) if w[b, k] >= 1e-6)
        z = run_filter(synth[k], mixed * carriers[k], zero_phase)
        band_outputs.append(z)
        out += z
    rms_x, rms_y = np.sqrt(np.mean(x ** 2)), np.sqrt(np.mean(out ** 2))
    if rms_y > 0:
        out *= rms_x / rms_y
        band_outputs = [z * rms_x / rms_y for z in band_outputs]
    peak = np.max(np.abs(out)) if out.size else 0.0
    if peak > 1.0:
        out *= 0.999 / peak
    return (out, band_outputs, selection) if keep_bands else out


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
