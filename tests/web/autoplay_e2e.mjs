// The online study as a browser really treats it: Chromium's default
// autoplay policy (no --autoplay-policy flag), and nothing that puppeteer
// runs with a user gesture (page.evaluate, waitForFunction, waitForSelector,
// ElementHandle.click all call the page with userGesture: true). The page is
// watched by a probe injected at document start (no gesture), which reports
// through console messages (a page.exposeFunction binding would not do:
// puppeteer hands its result back with a gesture-carrying evaluate); the
// participant acts only through real input events
// (page.mouse.click on the Start button, then the keyboard on every screen:
// the keys each screen's text names). Checks: before the click the page has
// no user activation and no sound; after it every clip plays with sound (the
// AudioContext running, the element not muted, the probe's analyser on the
// context's output hears the clip within its file's sound onset window).
//
//   node tests/web/autoplay_e2e.mjs --avsi build/cli/avsi --work build/tests/web/autoplay_e2e [--chromium /usr/bin/chromium]
//        [--fault no-start-click | muted-clip]
//
// The faults show that the checks see a clip that starts muted or not at
// all: no-start-click replaces the participant's click with a script's
// element.click() (no user activation), muted-clip mutes each video element
// as it is added. Each must end in "not ok - clip …" lines (the ctest
// entries Autoplay.*Fault* require that output).
// Exit codes: 0 all checks passed, 1 a check failed, 77 skipped.
import fs from 'node:fs';
import path from 'node:path';
import {
  avsiRunner, check, finish, launchChromium, loadPuppeteer, parseArgs, prepareStudy, protocol, readCsv, serveStudy, source,
} from './harness.mjs';

const args = parseArgs(process.argv.slice(2));
const avsi = path.resolve(args.avsi || path.join(source, 'build/cli/avsi'));
const fault = args.fault || '';
const work = path.resolve(args.work || path.join(source, 'build/tests/web', `autoplay_e2e${fault ? `_${fault}` : ''}`));
const chromium = args.chromium || '/usr/bin/chromium';
if (fault && !['no-start-click', 'muted-clip'].includes(fault)) { console.error(`--fault: expected no-start-click or muted-clip, got "${fault}"`); process.exit(2); }
const puppeteer = loadPuppeteer(chromium);
// The analyser's level that counts as sound (RMS over 2048 samples).
const AUDIBLE_DBFS = -50;

const started = Date.now();
const { stimuli, study, config } = prepareStudy(avsi, work, 1);
const plan = config.subjects['1'];

// When each clip's own sound starts (its WAV beside the MP4 in the stimulus
// folder): the first 10 ms window at AUDIBLE_DBFS or above.
function readWavMono(file) {
  const b = fs.readFileSync(file);
  let offset = 12;
  let format = null;
  while (offset + 8 <= b.length) {
    const id = b.toString('ascii', offset, offset + 4);
    const size = b.readUInt32LE(offset + 4);
    if (id === 'fmt ') format = { code: b.readUInt16LE(offset + 8), channels: b.readUInt16LE(offset + 10), rate: b.readUInt32LE(offset + 12), bits: b.readUInt16LE(offset + 22) };
    if (id === 'data' && format) {
      const bytes = format.bits / 8;
      const n = Math.floor(size / bytes / format.channels);
      const out = new Float32Array(n);
      for (let i = 0; i < n; i++) {
        const at = offset + 8 + i * bytes * format.channels;
        out[i] = format.code === 3 ? b.readFloatLE(at) : format.bits === 16 ? b.readInt16LE(at) / 32768 : b.readInt32LE(at) / 2147483648;
      }
      return { samples: out, rate: format.rate };
    }
    offset += 8 + size + (size % 2);
  }
  throw new Error(`${file}: no PCM data`);
}
function soundOnsetMs(wavFile) {
  const { samples, rate } = readWavMono(wavFile);
  const w = Math.round(rate / 100);
  for (let i = 0; i + w <= samples.length; i += w) {
    let sum = 0;
    for (let k = i; k < i + w; k++) sum += samples[k] * samples[k];
    if (10 * Math.log10(sum / w + 1e-20) >= AUDIBLE_DBFS) return (i / rate) * 1000;
  }
  return null;
}

// The probe: runs in the page before the study, reports screens and clips.
const probe = (options) => {
  // Through the console: a binding (page.exposeFunction) would answer with a gesture-carrying evaluate.
  const log = console.debug.bind(console);
  const report = (event) => log(`avsiProbe ${JSON.stringify(event)}`);
  let tap = null;
  const connect = AudioNode.prototype.connect;
  // Every node connected to the output is also connected to one analyser per context.
  AudioNode.prototype.connect = function (destination, ...rest) {
    const out = connect.call(this, destination, ...rest);
    if (destination instanceof AudioDestinationNode) {
      if (!tap || tap.context !== this.context) {
        const analyser = this.context.createAnalyser();
        analyser.fftSize = 2048;
        const silent = this.context.createGain();
        silent.gain.value = 0;
        connect.call(analyser, silent);
        connect.call(silent, destination);
        tap = { context: this.context, analyser, buffer: new Float32Array(2048) };
      }
      connect.call(this, tap.analyser);
    }
    return out;
  };
  const level = () => {
    if (!tap) return -Infinity;
    tap.analyser.getFloatTimeDomainData(tap.buffer);
    let sum = 0;
    for (const v of tap.buffer) sum += v * v;
    return 10 * Math.log10(sum / tap.buffer.length + 1e-20);
  };
  report({ type: 'load', activated: navigator.userActivation.hasBeenActive });
  // Each clip: first frame, sound onset (media time), state at the first frame.
  const watchVideo = (video) => {
    if (options.fault === 'muted-clip') video.muted = true;
    const clip = { type: 'clip', position: window.avsiStudy ? window.avsiStudy.currentPosition : 0, src: video.getAttribute('src') || '', firstFrameMs: null,
      startMs: null, soundMediaMs: null, peakDbfs: -Infinity, contextState: '', muted: null, volume: null, played: false };
    video.requestVideoFrameCallback((now, meta) => {
      clip.firstFrameMs = meta.expectedDisplayTime;
      clip.startMs = meta.expectedDisplayTime - meta.mediaTime * 1000;
      clip.contextState = tap ? tap.context.state : 'no audio graph';
      clip.muted = video.muted;
      clip.volume = video.volume;
      clip.played = true;
    });
    const timer = setInterval(() => {
      if (!video.paused && clip.startMs !== null) {
        const l = level();
        if (l > clip.peakDbfs) clip.peakDbfs = l;
        if (clip.soundMediaMs === null && l >= options.audibleDbfs) clip.soundMediaMs = performance.now() - clip.startMs;
      }
    }, 5);
    const done = () => { clearInterval(timer); report(Object.assign({}, clip, { peakDbfs: Number.isFinite(clip.peakDbfs) ? clip.peakDbfs : null })); };
    video.addEventListener('ended', done, { once: true });
    video.addEventListener('error', done, { once: true });
  };
  // Screens: the text, the buttons (with where they are), the answer box.
  let last = '';
  const screen = () => {
    for (const v of document.querySelectorAll('video')) if (!v.dataset.probed) { v.dataset.probed = '1'; watchVideo(v); }
    const buttons = [...document.querySelectorAll('button')].map((b) => { const r = b.getBoundingClientRect(); return { text: b.textContent.trim(), disabled: b.disabled, x: r.x + r.width / 2, y: r.y + r.height / 2 }; });
    const text = document.body ? document.body.innerText.trim().slice(0, 600) : '';
    const input = document.querySelector('#avsi-answer');
    const state = { type: 'screen', text, buttons, answer: !!input && document.activeElement === input,
      position: window.avsiStudy ? window.avsiStudy.currentPosition : 0, outbox: window.avsiStudy ? window.avsiStudy.outbox : -1,
      screening: null, activated: navigator.userActivation.hasBeenActive };
    const m = /Sound check (\d+) of/.exec(text);
    if (m && window.avsiStudy) state.screening = window.avsiStudy.screeningAnswer(/softest/.test(text) ? 'antiphase' : 'huggins', Number(m[1]));
    const key = JSON.stringify(state);
    if (key !== last) { last = key; report(state); }
    if (options.fault === 'no-start-click') {
      const start = [...document.querySelectorAll('button')].find((b) => b.textContent === 'Start' && !b.disabled && !b.dataset.probeClicked);
      if (start) { start.dataset.probeClicked = '1'; start.click(); }
    }
  };
  new MutationObserver(screen).observe(document, { subtree: true, childList: true, attributes: true, characterData: true });
  setInterval(screen, 200);
};

const { base, close } = await serveStudy(study, {
  '/results': (req, res) => { res.writeHead(204); res.end(); },
  '/complete': (req, res) => { res.writeHead(200, { 'Content-Type': 'text/html' }); res.end('<p>complete</p>'); },
});
const browser = await launchChromium(puppeteer, chromium, path.join(work, 'profile'));
const clips = [];
let screenNow = { text: '', buttons: [] };
let loadActivated = null;
const waiters = [];
const typed = {};
try {
  const page = await browser.newPage();
  const pageErrors = [];
  page.on('pageerror', (e) => pageErrors.push(String(e)));
  page.on('console', (message) => {
    const text = message.text();
    if (!text.startsWith('avsiProbe ')) return;
    const event = JSON.parse(text.slice('avsiProbe '.length));
    if (event.type === 'load') loadActivated = event.activated;
    if (event.type === 'screen') screenNow = event;
    if (event.type === 'clip') clips.push(event);
    for (const w of waiters.slice()) if (w.test()) { waiters.splice(waiters.indexOf(w), 1); w.resolve(); }
  });
  await page.evaluateOnNewDocument(probe, { fault, audibleDbfs: AUDIBLE_DBFS });
  // Waits until `test` holds for the reported screen (no page call).
  const waitFor = (what, test, timeoutMs = 20000) => new Promise((resolve, reject) => {
    if (test()) { resolve(); return; }
    const w = { test, resolve: () => { clearTimeout(w.timer); resolve(); } };
    w.timer = setTimeout(() => { waiters.splice(waiters.indexOf(w), 1); reject(new Error(`timed out waiting for ${what}; the screen says: ${screenNow.text.replace(/\s+/g, ' ').slice(0, 200)}`)); }, timeoutMs);
    waiters.push(w);
  });
  const button = (t) => screenNow.buttons.find((b) => b.text === t && !b.disabled);
  const says = (re) => re.test(screenNow.text);
  // Presses `key` on a screen and checks that the screen moved on.
  const pressOn = async (what, key, leaves) => {
    await page.keyboard.press(key);
    try {
      await waitFor(`${what} to end after ${key}`, () => !leaves());
      check(true, `${what}: ${key === ' ' ? 'Space' : key} works`);
    } catch (e) {
      check(false, `${what}: ${key === ' ' ? 'Space' : key} works`, e.message);
      throw e;
    }
  };
  const typeAnswer = async (position, text) => {
    await waitFor(`the answer box of trial ${position}`, () => screenNow.answer && screenNow.position === position);
    if (text) await page.keyboard.type(text);
    await page.keyboard.press('Enter');
    typed[position] = text;
  };

  await page.goto(`${base}/index.html?subject=1`);
  await waitFor('the Start screen', () => !!button('Start'));
  check(loadActivated === false && screenNow.activated === false, 'before the participant acts, the page has no user activation');
  if (fault !== 'no-start-click') {
    const start = button('Start');
    await page.mouse.click(start.x, start.y);
  }
  try {
    await waitFor('the level screen', () => says(/steady noise/) && !!button('The level is comfortable'), 15000);
  } catch (e) {
    console.log(`# ${e.message}`);
  }
  check(says(/steady noise/), 'after the Start click the study goes on with sound (the level screen)');
  if (says(/steady noise/)) {
    // Every further screen by the keys it names.
    await pressOn('level screen', 'Enter', () => says(/steady noise/));
    for (const [test, trials] of [['antiphase', 3], ['huggins', 3]]) {
      await waitFor(`the ${test} introduction`, () => !!button('Begin'));
      await pressOn(`${test} introduction ("Space or Enter: begin")`, ' ', () => !!button('Begin'));
      for (let i = 1; i <= trials; i++) {
        await waitFor(`sound check ${i}`, () => screenNow.screening !== null && says(new RegExp(`Sound check ${i} of`)) && !!button('1'));
        await pressOn(`${test} check ${i} ("Keys 1, 2, 3")`, String(screenNow.screening), () => says(new RegExp(`Sound check ${i} of`)));
      }
    }
    await waitFor('the instructions', () => !!button('Begin'));
    await pressOn('instructions ("Space or Enter: begin")', 'Enter', () => !!button('Begin'));
    await typeAnswer(1, 'the sun is warm');
    await waitFor('the practice instructions', () => !!button('Begin'));
    await pressOn('practice instructions', ' ', () => !!button('Begin'));
    await typeAnswer(2, '');
    await waitFor('the empty-answer question', () => says(/Submit an empty answer\?/));
    await pressOn('empty-answer question ("No, type again (N)")', 'n', () => says(/Submit an empty answer\?/));
    await typeAnswer(2, 'she opened the door');
    await waitFor('the practice feedback', () => says(/The sentence was:/));
    await pressOn('practice feedback ("Space or Enter: continue")', ' ', () => says(/The sentence was:/));
    await waitFor('the test instructions', () => !!button('Begin'));
    await pressOn('test instructions', 'Enter', () => !!button('Begin'));
    await typeAnswer(3, '');
    await waitFor('the empty-answer question', () => says(/Submit an empty answer\?/));
    await pressOn('empty-answer question ("Yes, submit it (Y)")', 'y', () => says(/Submit an empty answer\?/));
    await waitFor('the break screen', () => says(/Press Space to continue/));
    await pressOn('break screen ("Press Space to continue")', ' ', () => says(/Press Space to continue/));
    await typeAnswer(4, 'he bought bread');
    await waitFor('the end screen', () => !!button('Finish'));
  }
  check(pageErrors.length === 0, 'no page errors', pageErrors.join('; '));
} catch (e) {
  check(false, 'the participant reached the end of the study', e.message);
} finally {
  await browser.close();
  close();
}

// Every planned clip played with sound.
for (const t of plan) {
  const clip = clips.find((c) => c.position === t.position);
  const file = config.stimuli[t.stimulus].file;
  const wav = path.join(stimuli, file.replace(/^stimuli\//, '').replace(/\.mp4$/, '.wav'));
  const onset = fs.existsSync(wav) ? soundOnsetMs(wav) : null;
  const detail = clip ? `context ${clip.contextState}, muted ${clip.muted}, volume ${clip.volume}, peak ${clip.peakDbfs === null ? '-inf' : clip.peakDbfs.toFixed(1)} dBFS, ` +
    `sound at ${clip.soundMediaMs === null ? 'never' : clip.soundMediaMs.toFixed(0)} ms (the file's from ${onset === null ? '?' : onset.toFixed(0)} ms)` : 'never played';
  const withSound = !!clip && clip.played && clip.contextState === 'running' && clip.muted === false && clip.volume > 0;
  // Sound from the first 300 ms after the file's own onset (the audio path, ~35 ms here, and the 5 ms polling) on.
  const heard = !!clip && clip.soundMediaMs !== null && (onset === null || (clip.soundMediaMs >= onset - 50 && clip.soundMediaMs <= onset + 300));
  check(withSound && heard, `clip of trial ${t.position} (${t.condition} ${t.sentence}) starts with sound: ${detail}`);
}
finish(`autoplay e2e${fault ? ` (fault ${fault})` : ''}`, started);
