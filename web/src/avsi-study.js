// The avsi online study runtime (jsPsych 8): the lab runner's session flow in
// a browser, with headphone screening, a comfortable-level step, per-trial
// result records, resume at the first unanswered trial, and per-trial A/V
// timing. `avsi export-web` copies this file into each study beside
// study.json, which holds everything that depends on the protocol.
//
// Flow (mirrors experiment/src/session.cpp): start screen (the first user
// gesture starts the AudioContext), level setting with calibration noise,
// headphone checks (Woods et al. 2017 antiphase; Milne et al. 2021 Huggins
// pitch), then per block: preload with a progress bar (and a failure screen),
// instructions at each phase change, breaks between test blocks (and every
// `break_every` trials), trials (fixation, the clip, a blank, the answer box,
// "empty answer?" confirmation, the sentence text after practice trials),
// and the end screen with the protocol's completion URL.
//
// Records: one JSON object per event, kept in a localStorage outbox until
// the destination confirms it: JATOS (jatos.appendResultData), or the
// protocol's results_url (POST, JSON Lines), or, with neither, a download on
// the end screen. One sender delivers the outbox: one request in flight at a
// time (the oldest unsent records, one line each), after a failure a wait
// that doubles from 3 s up to 60 s with jitter, kept in localStorage so a
// reload does not retry early, and reset by a success. Every record has
// avsi (its kind), study, experiment, subject, run (this browser's run of
// the subject, kept across reloads), session (this page load), seq (per
// subject and run, across reloads) and time_utc; `avsi import-web` checks
// them against the design.
//
// Resume: the answered positions, screening and level results are kept in
// localStorage and in JATOS' study-session data; a reload starts again at
// the first unanswered trial with the same lists (the plan is the subject's
// row set in study.json).
//
// Timing (per trial): requestVideoFrameCallback gives each presented frame's
// media time and expected display time; the audio heard at that moment is
// estimated from the element's media clock minus the AudioContext's output
// and base latencies, giving an audio-video offset per frame (positive: video
// late), frames shown/dropped/repeated, and the browser's own
// getVideoPlaybackQuality counts.
(function () {
  'use strict';

  const STORAGE_PREFIX = 'avsi:';
  // The sender's retry waits: the n-th failure in a row waits a uniform
  // random time in [d/2, d], d = min(SEND_RETRY_MAX_MS, SEND_RETRY_FIRST_MS * 2^(n-1)).
  const SEND_RETRY_FIRST_MS = 3000;
  const SEND_RETRY_MAX_MS = 60000;
  const SEND_TIMEOUT_MS = 30000;   // a request not answered by then counts as failed
  const SEND_BATCH = 100;          // records per request at most

  // ---- small helpers ------------------------------------------------------

  function escapeHtml(text) {
    return String(text).replace(/[&<>"']/g, (c) => ({ '&': '&amp;', '<': '&lt;', '>': '&gt;', '"': '&quot;', "'": '&#39;' })[c]);
  }
  function textHtml(text) { return `<div class="avsi-text">${escapeHtml(text)}</div>`; }
  // A text of the study's language (study.json "strings", from
  // protocols/languages/<lang>/strings.toml) with its {placeholders} filled.
  function T(section, key, values) {
    const text = Study.config.strings[section][key];
    if (text === undefined) throw new Error(`study.json has no text ${section}.${key}`);
    return text.replace(/\{(\w+)\}/g, (whole, name) => (values && name in values ? String(values[name]) : whole));
  }
  function sleep(ms) { return new Promise((resolve) => setTimeout(resolve, ms)); }
  function nowUtc() { return new Date().toISOString(); }
  function randomId() {
    const bytes = new Uint8Array(8);
    crypto.getRandomValues(bytes);
    return Array.from(bytes, (b) => b.toString(16).padStart(2, '0')).join('');
  }
  // FNV-1a, then mulberry32: a seeded generator for the screening orders.
  function seededRandom(text) {
    let h = 2166136261;
    for (let i = 0; i < text.length; i++) { h ^= text.charCodeAt(i); h = Math.imul(h, 16777619); }
    let a = h >>> 0;
    return function () {
      a = (a + 0x6D2B79F5) >>> 0;
      let t = a;
      t = Math.imul(t ^ (t >>> 15), t | 1);
      t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
      return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
    };
  }
  function shuffled(items, random) {
    const out = items.slice();
    for (let i = out.length - 1; i > 0; i--) {
      const j = Math.floor(random() * (i + 1));
      [out[i], out[j]] = [out[j], out[i]];
    }
    return out;
  }
  function median(values) {
    if (!values.length) return 0;
    const s = values.slice().sort((a, b) => a - b);
    return s[Math.floor(s.length / 2)];
  }
  // Resolves on the next key in `keys` (KeyboardEvent.key values).
  function waitForKey(keys, signal) {
    return new Promise((resolve) => {
      const handler = (e) => {
        if (keys.includes(e.key)) { document.removeEventListener('keydown', handler); resolve(e.key); }
      };
      document.addEventListener('keydown', handler);
      if (signal) signal.addEventListener('abort', () => document.removeEventListener('keydown', handler));
    });
  }
  // Resolves with the clicked button's value or a matching key.
  function waitForChoice(display, keyMap) {
    return new Promise((resolve) => {
      const controller = new AbortController();
      const done = (value) => { controller.abort(); resolve(value); };
      display.querySelectorAll('button[data-value]').forEach((b) =>
        b.addEventListener('click', () => done(b.dataset.value), { signal: controller.signal }));
      document.addEventListener('keydown', (e) => {
        if (e.target && e.target.tagName === 'INPUT') return;
        if (keyMap && Object.prototype.hasOwnProperty.call(keyMap, e.key)) { e.preventDefault(); done(keyMap[e.key]); }
      }, { signal: controller.signal });
    });
  }

  // ---- the study ----------------------------------------------------------

  const Study = {
    config: null,
    subject: 0,
    plan: [],
    sessionId: randomId(),
    jatos: false,
    state: null,
    ctx: null,
    refreshHz: 0,
    sounds: new Map(),
    currentPosition: 0,
    jsPsych: null,
    preloadFailure: null,
    screeningFailed: false,
    otherRun: '',
  };

  function storageKey() { return `${STORAGE_PREFIX}${Study.config.study_id}:${Study.subject}`; }

  function emptyState() {
    return { run: randomId(), answered: [], seq: 0, level_done: false, screening: {}, outbox: [], log: [], send_failures: 0, send_after_ms: 0 };
  }

  // The saved state: localStorage merged with JATOS' study-session data.
  function loadState() {
    const state = emptyState();
    let savedHere = false;
    try {
      const saved = JSON.parse(localStorage.getItem(storageKey()) || 'null');
      if (saved) { Object.assign(state, saved); savedHere = !!saved.run; }
    } catch (e) { /* a damaged entry is replaced */ }
    if (Study.jatos && jatos.studySessionData && jatos.studySessionData.avsi &&
        jatos.studySessionData.avsi.subject === Study.subject) {
      const s = jatos.studySessionData.avsi;
      // The same worker's study session continues its run (localStorage lost or another tab).
      if (s.run && !savedHere) state.run = s.run;
      state.answered = Array.from(new Set([...(state.answered || []), ...(s.answered || [])])).sort((a, b) => a - b);
      state.seq = Math.max(state.seq || 0, s.seq || 0);
      state.level_done = state.level_done || !!s.level_done;
      state.screening = Object.assign({}, s.screening || {}, state.screening || {});
    }
    return state;
  }

  // The state in this browser's localStorage only.
  function saveLocalState() {
    try {
      localStorage.setItem(storageKey(), JSON.stringify(Study.state));
    } catch (e) {
      console.warn('avsi: cannot save the state in localStorage', e);
    }
  }

  // The state in localStorage and (under JATOS) the study-session data.
  function saveState() {
    saveLocalState();
    if (Study.jatos) {
      const s = Study.state;
      jatos.studySessionData = Object.assign({}, jatos.studySessionData || {}, {
        avsi: { subject: Study.subject, run: s.run, answered: s.answered, seq: s.seq, level_done: s.level_done, screening: s.screening },
      });
      Promise.resolve(jatos.setStudySessionData(jatos.studySessionData)).catch(() => {});
    }
  }

  // ---- the sender -----------------------------------------------------------

  const Sender = { inFlight: false, timer: null, requests: 0 };

  // Delivers `records` (the oldest of the outbox) in one request; resolves
  // true once the destination confirmed them.
  async function deliver(records) {
    const text = records.map((r) => JSON.stringify(r) + '\n').join('');
    if (Study.jatos) {
      try { await jatos.appendResultData(text); return true; } catch (e) { return false; }
    }
    const url = Study.config.online.results_url;
    if (!url) return true;  // download mode: the log is the data
    const abort = new AbortController();
    const timer = setTimeout(() => abort.abort(), SEND_TIMEOUT_MS);
    try {
      const response = await fetch(url, { method: 'POST', headers: { 'Content-Type': 'application/x-ndjson' }, body: text, keepalive: text.length < 60000, signal: abort.signal });
      return response.ok;
    } catch (e) {
      return false;
    } finally {
      clearTimeout(timer);
    }
  }

  // The wait after the n-th failure in a row (see SEND_RETRY_*): "equal jitter".
  function retryWaitMs(failures) {
    const d = Math.min(SEND_RETRY_MAX_MS, SEND_RETRY_FIRST_MS * 2 ** Math.min(failures - 1, 30));
    return d / 2 + Math.random() * (d / 2);
  }

  function scheduleSend(waitMs) {
    if (Sender.timer) clearTimeout(Sender.timer);
    Sender.timer = setTimeout(() => { Sender.timer = null; sendNext(); }, Math.max(0, waitMs));
  }

  // Sends the head of the outbox unless a request is in flight or a retry
  // wait (of this page or, through localStorage, of an earlier one) runs.
  function kickSender() {
    const s = Study.state;
    if (!s || Sender.inFlight || Sender.timer || !s.outbox.length) return;
    const wait = (s.send_after_ms || 0) - Date.now();
    if (wait > 0) scheduleSend(wait); else sendNext();
  }

  // The one place that sends: one request at a time; on success the next
  // batch at once, on failure the next attempt after the retry wait.
  async function sendNext() {
    const s = Study.state;
    if (Sender.inFlight || !s.outbox.length) return;
    if (Sender.timer) { clearTimeout(Sender.timer); Sender.timer = null; }
    Sender.inFlight = true;
    const batch = s.outbox.slice(0, SEND_BATCH);
    Sender.requests++;
    let ok = false;
    try { ok = await deliver(batch); } finally { Sender.inFlight = false; }
    if (ok) {
      s.outbox.splice(0, batch.length);
      s.send_failures = 0;
      s.send_after_ms = 0;
      saveLocalState();
      if (s.outbox.length) sendNext();
    } else {
      s.send_failures = (s.send_failures || 0) + 1;
      const wait = retryWaitMs(s.send_failures);
      s.send_after_ms = Date.now() + wait;
      saveLocalState();
      scheduleSend(wait);
    }
  }

  // Records an event: kept, queued and sent.
  function emit(kind, fields) {
    const record = Object.assign({
      avsi: kind, study: Study.config.study_id, experiment: Study.config.experiment, subject: Study.subject,
      run: Study.state.run, session: Study.sessionId, seq: ++Study.state.seq, time_utc: nowUtc(),
    }, fields);
    Study.state.log.push(record);
    Study.state.outbox.push(record);
    saveState();
    kickSender();
    return record;
  }

  // The participant asked to finish: one attempt now (unless one is in
  // flight), then wait up to `timeoutMs` for the outbox to empty.
  async function waitForOutbox(timeoutMs) {
    const end = performance.now() + timeoutMs;
    if (!Sender.inFlight) sendNext();
    while (Study.state.outbox.length && performance.now() < end) await sleep(100);
    return Study.state.outbox.length === 0;
  }

  // Every record of this subject so far, one JSON object a line (the download).
  function resultsText() { return Study.state.log.map((r) => JSON.stringify(r)).join('\n') + '\n'; }

  function downloadResults() {
    const blob = new Blob([resultsText()], { type: 'application/x-ndjson' });
    const a = document.createElement('a');
    a.href = URL.createObjectURL(blob);
    a.download = `avsi-${Study.config.experiment}-subject${Study.subject}.json`;
    document.body.appendChild(a);
    a.click();
    a.remove();
  }

  // The correct interval (1–3) and the sounds of one screening trial.
  function screeningTrial(test, index) {
    const random = seededRandom(`${Study.config.study_id}/${Study.subject}/${test}/${index}`);
    const sounds = Study.config.sounds[test];
    if (test === 'antiphase') {
      const order = shuffled(['standard', 'soft', 'antiphase'], random);
      return { answer: order.indexOf('soft') + 1, files: order.map((k) => sounds[k]) };
    }
    const target = Math.floor(random() * 3);
    const noises = shuffled([0, 1, 2], random);
    const files = [0, 1, 2].map((i) => (i === target ? sounds.pitch[index % 3] : sounds.noise[noises[i]]));
    return { answer: target + 1, files };
  }

  // ---- subject ------------------------------------------------------------

  function urlSubject() {
    const params = Study.jatos && jatos.urlQueryParameters ? jatos.urlQueryParameters : Object.fromEntries(new URLSearchParams(location.search));
    return params.subject !== undefined ? String(params.subject) : null;
  }

  // Under JATOS without ?subject: the worker's earlier number (study-session
  // or batch-session data), else the lowest free one, claimed in the batch
  // session (its versioning refuses a concurrent claim; then try again).
  async function jatosSubject(available) {
    if (jatos.studySessionData && jatos.studySessionData.avsi && jatos.studySessionData.avsi.subject)
      return jatos.studySessionData.avsi.subject;
    const workerKey = `avsi_worker_${jatos.workerId}`;
    for (let attempt = 0; attempt < 8; attempt++) {
      const all = jatos.batchSession.getAll() || {};
      if (all[workerKey]) return all[workerKey];
      const taken = new Set(Object.keys(all).filter((k) => k.startsWith('avsi_subject_')).map((k) => Number(k.slice(13))));
      const free = available.find((n) => !taken.has(n));
      if (free === undefined) return null;
      try {
        await jatos.batchSession.set(`avsi_subject_${free}`, jatos.workerId);
        await jatos.batchSession.set(workerKey, free);
        return free;
      } catch (e) {
        await sleep(200 + 300 * Math.random());
      }
    }
    return null;
  }

  async function resolveSubject() {
    const available = Object.keys(Study.config.subjects).map(Number).sort((a, b) => a - b);
    const fromUrl = urlSubject();
    let subject = null;
    if (fromUrl !== null) {
      subject = /^[0-9]+$/.test(fromUrl) ? Number(fromUrl) : NaN;
      if (!available.includes(subject))
        throw new Error(T('web', 'subject_unknown', { subject: fromUrl, first: available[0], last: available[available.length - 1] }));
      return subject;
    }
    if (Study.jatos) {
      subject = await jatosSubject(available);
      if (subject === null) throw new Error(T('web', 'subjects_in_use'));
      return subject;
    }
    throw new Error(T('web', 'subject_missing'));
  }

  // Claims the subject for this browser's run: under JATOS in the batch
  // session (avsi_run_<subject>); resolves the other run's id when another
  // browser holds the claim, else ''. Without JATOS a browser cannot know
  // of another; the start screen of a new run says so (runNotice).
  async function claimRun() {
    if (!Study.jatos || !jatos.batchSession) return '';
    const key = `avsi_run_${Study.subject}`;
    for (let attempt = 0; attempt < 4; attempt++) {
      const holder = jatos.batchSession.get(key);
      if (holder) return holder === Study.state.run ? '' : String(holder);
      try { await jatos.batchSession.set(key, Study.state.run); return ''; } catch (e) { await sleep(200 + 300 * Math.random()); }
    }
    return '';
  }

  // The start screen's warning about a second run of the same subject.
  function runNotice() {
    if (Study.otherRun)
      return `<div class="avsi-text avsi-error">${escapeHtml(T('web', 'other_run'))}</div>`;
    const fresh = Study.state.answered.length === 0 && Study.state.seq === 0;
    if (fresh && !Study.jatos)
      return `<div class="avsi-hint">${escapeHtml(T('web', 'other_browser'))}</div>`;
    return '';
  }

  // ---- plugins --------------------------------------------------------------

  const { ParameterType } = jsPsychModule;

  // The start screen: the click starts the AudioContext (browsers block
  // sound until a user gesture), then sounds are decoded and the display's
  // refresh rate measured.
  class StartPlugin {
    static info = { name: 'avsi-start', version: '1', parameters: { resumed: { type: ParameterType.BOOL, default: false } }, data: {} };
    constructor(jsPsych) { this.jsPsych = jsPsych; }
    async trial(display, trial, on_load) {
      display.innerHTML = textHtml(trial.resumed ? T('web', 'resume_text') : T('web', 'start_text'))
        + runNotice()
        + `<div id="avsi-start-status" class="avsi-hint"></div><button class="jspsych-btn" data-value="start">${escapeHtml(T('web', 'start_button'))}</button>`
        + `<div class="avsi-hint">${escapeHtml(T('web', 'start_keys'))}</div>`;
      on_load();
      const status = display.querySelector('#avsi-start-status');
      for (;;) {
        await waitForChoice(display, { Enter: 'start', ' ': 'start' });
        const ctx = this.jsPsych.pluginAPI.audioContext();
        try {
          // Without a user gesture Chromium leaves resume() pending: wait a second at most.
          await Promise.race([ctx.resume(), sleep(1000)]);
          const silence = ctx.createBufferSource();
          silence.buffer = ctx.createBuffer(1, 1, ctx.sampleRate);
          silence.connect(ctx.destination);
          silence.start();
        } catch (e) { /* reported below */ }
        if (ctx.state === 'running') { Study.ctx = ctx; break; }
        status.textContent = T('web', 'sound_failed');
      }
      status.textContent = T('web', 'loading');
      display.querySelector('button').disabled = true;
      await loadSounds();
      Study.refreshHz = await measureRefresh(40);
      const ctx = Study.ctx;
      return emit('session', {
        position: firstUnanswered() ? firstUnanswered().position : 0,
        resumed: !!trial.resumed,
        browser: {
          user_agent: navigator.userAgent,
          platform: (navigator.userAgentData && navigator.userAgentData.platform) || navigator.platform || '',
          language: navigator.language || '',
          screen: `${screen.width}x${screen.height}`,
          device_pixel_ratio: window.devicePixelRatio || 1,
          refresh_hz: Math.round(Study.refreshHz * 100) / 100,
          audio_sample_rate_hz: ctx.sampleRate,
          audio_base_latency_ms: (ctx.baseLatency || 0) * 1000,
          audio_output_latency_ms: (ctx.outputLatency || 0) * 1000,
          video_frame_callbacks: 'requestVideoFrameCallback' in HTMLVideoElement.prototype,
          jatos: Study.jatos,
          jatos_worker: Study.jatos ? String(jatos.workerId) : '',
        },
        other_run: Study.otherRun || '',
      });
    }
  }

  async function loadSounds() {
    const urls = [];
    const s = Study.config.sounds;
    if (s.antiphase) urls.push(s.antiphase.standard, s.antiphase.soft, s.antiphase.antiphase);
    if (s.huggins) urls.push(...s.huggins.pitch, ...s.huggins.noise);
    if (s.calibration) urls.push(s.calibration);
    for (const url of urls) {
      if (Study.sounds.has(url)) continue;
      const response = await fetch(url);
      if (!response.ok) throw new Error(T('web', 'sound_load_failed', { file: url, status: response.status }));
      Study.sounds.set(url, await Study.ctx.decodeAudioData(await response.arrayBuffer()));
    }
  }

  // The display's refresh rate from requestAnimationFrame intervals (median).
  function measureRefresh(frames) {
    return new Promise((resolve) => {
      const times = [];
      const step = (t) => {
        times.push(t);
        if (times.length > frames) {
          const deltas = times.slice(1).map((v, i) => v - times[i]);
          const period = median(deltas);
          resolve(period > 0 ? 1000 / period : 0);
        } else requestAnimationFrame(step);
      };
      requestAnimationFrame(step);
    });
  }

  // The comfortable-level step: stimulus-shaped noise on a loop.
  class LevelPlugin {
    static info = { name: 'avsi-level', version: '1', parameters: {}, data: {} };
    constructor(jsPsych) { this.jsPsych = jsPsych; }
    async trial(display, trial, on_load) {
      const ctx = Study.ctx;
      const source = ctx.createBufferSource();
      source.buffer = Study.sounds.get(Study.config.sounds.calibration);
      source.loop = true;
      source.connect(ctx.destination);
      const start = performance.now();
      source.start();
      display.innerHTML = textHtml(T('web', 'level_text')) +
        `<button class="jspsych-btn" data-value="ok" disabled>${escapeHtml(T('web', 'level_button'))}</button><div class="avsi-hint">${escapeHtml(T('web', 'level_keys'))}</div>`;
      on_load();
      await sleep(1000);
      display.querySelector('button').disabled = false;
      await waitForChoice(display, { Enter: 'ok' });
      source.stop();
      Study.state.level_done = true;
      const record = emit('level', { played_ms: Math.round(performance.now() - start) });
      return record;
    }
  }

  // One headphone-check trial: three intervals, pick one.
  class ScreeningPlugin {
    static info = {
      name: 'avsi-screening', version: '1',
      parameters: { test: { type: ParameterType.STRING, default: 'antiphase' }, index: { type: ParameterType.INT, default: 1 }, total: { type: ParameterType.INT, default: 6 } },
      data: {},
    };
    constructor(jsPsych) { this.jsPsych = jsPsych; }
    async trial(display, trial, on_load) {
      const { answer, files } = screeningTrial(trial.test, trial.index);
      const question = T('web', trial.test === 'antiphase' ? 'antiphase_question' : 'huggins_question');
      display.innerHTML = `<div class="avsi-text">${escapeHtml(T('web', 'sound_check', { index: trial.index, total: trial.total, question }))}</div>` +
        '<div class="avsi-intervals">' + [1, 2, 3].map((i) => `<div class="avsi-interval" id="avsi-interval-${i}">${i}</div>`).join('') + '</div>' +
        '<div>' + [1, 2, 3].map((i) => `<button class="jspsych-btn" data-value="${i}" disabled>${i}</button>`).join('') + '</div>' +
        `<div class="avsi-hint">${escapeHtml(T('web', 'screening_keys'))}</div>`;
      on_load();
      const ctx = Study.ctx;
      const online = Study.config.online;
      const interval_s = (trial.test === 'antiphase' ? online.tone_ms : online.huggins_ms) / 1000;
      const step_s = interval_s + online.gap_ms / 1000;
      const t0 = ctx.currentTime + 0.3;
      files.forEach((file, i) => {
        const source = ctx.createBufferSource();
        source.buffer = Study.sounds.get(file);
        source.connect(ctx.destination);
        source.start(t0 + i * step_s);
      });
      // Light each box while its sound plays.
      for (let i = 0; i < 3; i++) {
        await sleep(Math.max(0, (t0 + i * step_s - ctx.currentTime) * 1000));
        display.querySelector(`#avsi-interval-${i + 1}`).classList.add('playing');
        await sleep(interval_s * 1000);
        display.querySelector(`#avsi-interval-${i + 1}`).classList.remove('playing');
      }
      display.querySelectorAll('button').forEach((b) => { b.disabled = false; });
      const shown = performance.now();
      const response = Number(await waitForChoice(display, { 1: '1', 2: '2', 3: '3' }));
      const record = emit('screening-trial', {
        test: trial.test, trial: trial.index, answer, response, correct: response === answer,
        response_time_ms: Math.round(performance.now() - shown),
      });
      return record;
    }
  }

  // A text screen (instructions, breaks) with a button that Space and Enter
  // press too, as in the lab runner (break_text says "Press Space to continue").
  class TextPlugin {
    static info = {
      name: 'avsi-text', version: '1',
      parameters: { text: { type: ParameterType.STRING, default: '' }, button: { type: ParameterType.STRING, default: 'Continue' } },
      data: {},
    };
    constructor(jsPsych) { this.jsPsych = jsPsych; }
    async trial(display, trial, on_load) {
      display.innerHTML = textHtml(trial.text) + `<button class="jspsych-btn" data-value="ok">${escapeHtml(trial.button)}</button>` +
        `<div class="avsi-hint">${escapeHtml(T('web', 'text_keys', { button: trial.button.toLowerCase() }))}</div>`;
      on_load();
      await waitForChoice(display, { ' ': 'ok', Enter: 'ok' });
      return { avsi_screen: 'text' };
    }
  }
  function textScreen(text, button) {
    return { type: TextPlugin, text, button: button || T('web', 'continue') };
  }

  // A screen that never ends (failures; the participant reloads or leaves).
  class StopPlugin {
    static info = { name: 'avsi-stop', version: '1', parameters: { html: { type: ParameterType.HTML_STRING, default: '' } }, data: {} };
    constructor(jsPsych) { this.jsPsych = jsPsych; }
    trial(display, trial, on_load) {
      display.innerHTML = trial.html;
      display.querySelectorAll('button[data-action="reload"]').forEach((b) => b.addEventListener('click', () => location.reload()));
      display.querySelectorAll('button[data-action="download"]').forEach((b) => b.addEventListener('click', downloadResults));
      on_load();
      return new Promise(() => {});
    }
  }

  // One trial: fixation, the clip (with timing), blank, answer, confirmation,
  // practice feedback. The record is sent when the answer is committed.
  class TrialPlugin {
    static info = { name: 'avsi-trial', version: '1', parameters: { trial: { type: ParameterType.OBJECT, default: undefined } }, data: {} };
    constructor(jsPsych) { this.jsPsych = jsPsych; }

    async trial(display, params, on_load) {
      const t = params.trial;
      const session = Study.config.session;
      const stimulus = Study.config.stimuli[t.stimulus];
      Study.currentPosition = t.position;
      display.dataset.avsiPosition = String(t.position);
      const progress = session.show_progress ? `<div class="avsi-progress">${escapeHtml(T('runner', 'progress', { position: t.position, total: Study.plan.length }))}</div>` : '';
      display.innerHTML = '<div class="avsi-fixation">+</div>' + progress;
      on_load();
      await sleep(session.fixation_ms);

      const timing = await this.present(display, stimulus);
      display.innerHTML = '';
      await sleep(session.response_delay_ms);

      // The answer box; Enter submits, an empty answer asks first.
      let text = '';
      let shown = 0;
      let confirmedEmpty = false;
      for (;;) {
        display.innerHTML = `<div class="avsi-text">${escapeHtml(T('runner', 'answer_prompt'))}</div>` +
          '<input class="avsi-answer" id="avsi-answer" type="text" autocomplete="off" autocorrect="off" autocapitalize="off" spellcheck="false">' +
          `<div class="avsi-hint">${escapeHtml(T('web', 'answer_keys'))}</div>` + progress;
        const input = display.querySelector('#avsi-answer');
        input.value = text;
        input.focus();
        if (!shown) shown = performance.now();
        text = await new Promise((resolve) => {
          input.addEventListener('keydown', (e) => { if (e.key === 'Enter') { e.preventDefault(); resolve(input.value); } });
        });
        if (text.trim() !== '') break;
        display.innerHTML = textHtml(T('runner', 'empty_answer')) +
          `<button class="jspsych-btn" data-value="yes">${escapeHtml(T('web', 'empty_yes'))}</button><button class="jspsych-btn" data-value="no">${escapeHtml(T('web', 'empty_no'))}</button>`;
        const choice = await waitForChoice(display, { y: 'yes', Y: 'yes', Enter: 'yes', n: 'no', N: 'no' });
        if (choice === 'yes') { text = ''; confirmedEmpty = true; break; }
      }
      const record = emit('trial', {
        position: t.position, phase: t.phase, block: t.block, list: t.list, condition: t.condition,
        sentence: t.sentence, stimulus: t.stimulus, stimulus_sha256: stimulus.sha256,
        response: text, response_time_ms: Math.round((performance.now() - shown) * 10) / 10, confirmed_empty: confirmedEmpty,
        timing: timing.summary, frames: timing.frames,
      });
      Study.state.answered.push(t.position);
      saveState();

      if (t.phase === 'practice') {
        display.innerHTML = textHtml(`${T('runner', 'feedback')}\n\n${t.text || ''}`) +
          `<button class="jspsych-btn" data-value="ok">${escapeHtml(T('web', 'continue'))}</button>` +
          `<div class="avsi-hint">${escapeHtml(T('web', 'text_keys', { button: T('web', 'continue').toLowerCase() }))}</div>` + progress;
        await waitForChoice(display, { ' ': 'ok', Enter: 'ok' });
      }
      return record;
    }

    // Plays the clip through the AudioContext and measures it.
    present(display, stimulus) {
      return new Promise((resolve) => {
        const ctx = Study.ctx;
        const video = document.createElement('video');
        video.className = 'avsi-video';
        video.playsInline = true;
        video.preload = 'auto';
        video.src = this.jsPsych.pluginAPI.getVideoBuffer(stimulus.file) || stimulus.file;
        display.innerHTML = '';
        display.appendChild(video);
        const source = ctx.createMediaElementSource(video);
        source.connect(ctx.destination);
        const samples = [];
        const haveCallbacks = 'requestVideoFrameCallback' in HTMLVideoElement.prototype;
        let ended = false;
        const onFrame = (now, meta) => {
          const ts = ctx.getOutputTimestamp ? ctx.getOutputTimestamp() : null;
          samples.push({ now, media: meta.mediaTime, expected: meta.expectedDisplayTime, presented: meta.presentedFrames, current: video.currentTime,
            // How far the AudioContext renders ahead of what is heard now (getOutputTimestamp).
            path: ts && ts.performanceTime > 0 ? (ctx.currentTime - ts.contextTime) - (performance.now() - ts.performanceTime) / 1000 : null });
          if (!ended) video.requestVideoFrameCallback(onFrame);
        };
        if (haveCallbacks) video.requestVideoFrameCallback(onFrame);
        const stall = setTimeout(() => fail(T('web', 'video_stalled')), (stimulus.frames / stimulus.fps + 15) * 1000);
        const fail = (why) => {
          ended = true;
          emit('preload-failed', { stimulus: stimulus.file, reason: why });
          display.innerHTML = textHtml(`${why} ${T('web', 'video_reload_text')}`) +
            `<button class="jspsych-btn" data-action="reload">${escapeHtml(T('web', 'reload'))}</button>`;
          display.querySelector('button').addEventListener('click', () => location.reload());
        };
        video.addEventListener('error', () => { clearTimeout(stall); fail(T('web', 'video_failed')); });
        video.addEventListener('ended', () => {
          clearTimeout(stall);
          ended = true;
          const quality = video.getVideoPlaybackQuality ? video.getVideoPlaybackQuality() : { droppedVideoFrames: 0, totalVideoFrames: 0 };
          resolve(measure(samples, stimulus, video, quality, haveCallbacks));
          source.disconnect();
          video.removeAttribute('src');
          video.load();
        });
        video.play().catch((e) => { clearTimeout(stall); fail(T('web', 'video_not_started', { error: e.name })); });
      });
    }
  }

  // The timing summary and per-frame rows of one presentation.
  function measure(samples, stimulus, video, quality, haveCallbacks) {
    const ctx = Study.ctx;
    // The audio output path: measured with getOutputTimestamp when the
    // browser gives it, else the AudioContext's stated latencies.
    const paths = samples.map((s) => s.path).filter((v) => v !== null && v > 0 && v < 1);
    const latency_s = paths.length ? median(paths) : (ctx.outputLatency || 0) + (ctx.baseLatency || 0);
    const seen = new Set();
    const frames = [];
    let repeated = 0;
    let missed = 0;
    let sum = 0;
    let maxAbs = 0;
    let previousPresented = null;
    for (const s of samples) {
      if (previousPresented !== null && s.presented - previousPresented > 1) missed += s.presented - previousPresented - 1;
      previousPresented = s.presented;
      const k = Math.round(s.media * stimulus.fps);
      if (k < 0 || k >= stimulus.frames) continue;
      if (seen.has(k)) { repeated++; continue; }
      seen.add(k);
      // The audio heard when this frame is displayed: the media clock at the
      // callback, moved to the display time, less the audio output path.
      const audioAt = s.current + (s.expected - s.now) / 1000 - latency_s;
      const offset = (audioAt - s.media) * 1000;
      sum += offset;
      maxAbs = Math.max(maxAbs, Math.abs(offset));
      frames.push([k, round6(s.media), round6(s.expected / 1000), Math.round(offset * 1000) / 1000]);
    }
    const first = samples.length ? samples[0] : null;
    const summary = {
      audio_onset_s: first ? round6(first.now / 1000 - first.current + latency_s) : 0,
      video_onset_s: frames.length ? frames[0][2] : 0,
      duration_s: round6(video.duration || stimulus.frames / stimulus.fps),
      refresh_hz: Math.round(Study.refreshHz * 1000) / 1000,
      frames_total: stimulus.frames,
      frames_shown: seen.size,
      dropped_frames: haveCallbacks ? stimulus.frames - seen.size : quality.droppedVideoFrames,
      repeated_frames: repeated,
      mean_offset_ms: frames.length ? Math.round((sum / frames.length) * 1000) / 1000 : 0,
      max_abs_offset_ms: Math.round(maxAbs * 1000) / 1000,
      frame_callbacks: haveCallbacks,
      presented_frames: samples.length ? samples[samples.length - 1].presented - samples[0].presented + 1 : 0,
      missed_callbacks: missed,
      browser_dropped_frames: quality.droppedVideoFrames || 0,
      browser_total_frames: quality.totalVideoFrames || 0,
      output_latency_ms: Math.round((ctx.outputLatency || 0) * 1e6) / 1000,
      base_latency_ms: Math.round((ctx.baseLatency || 0) * 1e6) / 1000,
      audio_path_ms: Math.round(latency_s * 1e6) / 1000,
      audio_path_measured: paths.length > 0,
    };
    return { summary, frames };
  }
  function round6(v) { return Math.round(v * 1e6) / 1e6; }

  // ---- the timeline -------------------------------------------------------

  function firstUnanswered() {
    const answered = new Set(Study.state.answered);
    return Study.plan.find((t) => !answered.has(t.position)) || null;
  }

  function phaseText(phase) {
    const s = Study.config.session;
    return phase === 'warmup' ? s.instructions : phase === 'practice' ? s.practice_instructions : s.test_instructions;
  }

  function screeningNodes(test) {
    const spec = Study.config.online[test];
    const nodes = [];
    nodes.push(textScreen(T('web', test === 'antiphase' ? 'antiphase_intro' : 'huggins_intro'), T('web', 'begin')));
    for (let i = 1; i <= spec.trials; i++) nodes.push({ type: ScreeningPlugin, test, index: i, total: spec.trials });
    let summary = null;
    nodes.push({
      type: jsPsychHtmlButtonResponse, stimulus: '', choices: [], trial_duration: 0,
      on_finish: (data) => { Object.assign(data, summary); },
      on_start: () => {
        const trials = Study.state.log.filter((r) => r.avsi === 'screening-trial' && r.test === test && r.session === Study.sessionId);
        const correct = trials.filter((r) => r.correct).length;
        const passed = correct >= spec.pass;
        Study.state.screening[test] = { trials: spec.trials, correct, required: spec.pass, passed };
        summary = emit('screening', { test, trials: spec.trials, correct, required: spec.pass, passed });
        if (!passed) Study.screeningFailed = true;
      },
    });
    return nodes;
  }

  function failScreeningScreen() {
    const url = Study.config.online.screening_fail_url;
    return {
      timeline: [{
        type: StopPlugin,
        html: textHtml(T('web', 'screening_failed')) +
          (url ? `<a class="jspsych-btn" href="${escapeHtml(url)}">${escapeHtml(T('web', 'continue'))}</a>` : ''),
        on_start: () => { emit('end', { answered: Study.state.answered.length, total: Study.plan.length, completed: false, reason: 'screening' }); },
      }],
      conditional_function: () => Study.config.online.end_on_screening_fail && Study.screeningFailed,
    };
  }

  function preloadNodes(trials) {
    const urls = Array.from(new Set(trials.map((t) => Study.config.stimuli[t.stimulus].file)));
    return [{
      type: jsPsychPreload,
      video: urls,
      show_progress_bar: true,
      message: `<div class="avsi-text">${escapeHtml(T('web', 'preload_text'))}</div>`,
      max_load_time: Study.config.online.preload_timeout_s * 1000,
      continue_after_error: true,
      show_detailed_errors: false,
      data: { avsi_screen: 'preload' },
      on_finish: (data) => {
        if (!data.success) {
          Study.preloadFailure = { files: (data.failed_video || []).length, timeout: !!data.timeout };
          emit('preload-failed', { position: trials[0].position, failed: data.failed_video || [], timeout: !!data.timeout });
        }
      },
    }, {
      timeline: [{
        type: StopPlugin,
        html: `<div class="avsi-text avsi-error">${escapeHtml(T('web', 'videos_failed'))}</div>` +
          textHtml(T('web', 'videos_reload_text')) +
          `<button class="jspsych-btn" data-action="reload">${escapeHtml(T('web', 'reload'))}</button>`,
      }],
      conditional_function: () => Study.preloadFailure !== null,
    }];
  }

  function endNode() {
    return {
      type: StopPlugin,
      html: '',
      on_start: (trial) => {
        emit('end', { answered: Study.state.answered.length, total: Study.plan.length, completed: !firstUnanswered() });
        const online = Study.config.online;
        const download = !Study.jatos && !online.results_url;
        trial.html = textHtml(Study.config.session.end_text) +
          '<div id="avsi-end-status" class="avsi-hint"></div>' +
          (download ? `<div class="avsi-text">${escapeHtml(T('web', 'download_text'))}</div><button class="jspsych-btn" data-action="download">${escapeHtml(T('web', 'download'))}</button>` : '') +
          `<button class="jspsych-btn" id="avsi-finish">${escapeHtml(T('web', 'finish'))}</button>`;
      },
      on_load: () => {
        const button = document.querySelector('#avsi-finish');
        const status = document.querySelector('#avsi-end-status');
        button.addEventListener('click', async () => {
          button.disabled = true;
          status.textContent = T('web', 'saving');
          const sent = await waitForOutbox(20000);
          if (!sent) {
            status.textContent = T('web', 'send_failed');
            button.disabled = false;
            const d = document.createElement('button');
            d.className = 'jspsych-btn';
            d.textContent = T('web', 'download');
            d.addEventListener('click', downloadResults);
            button.after(d);
            return;
          }
          const url = Study.config.online.completion_url;
          status.textContent = T('web', 'thanks_close');
          if (Study.jatos) {
            if (url) jatos.endStudyAndRedirect(url, true); else jatos.endStudy(true);
          } else if (url) {
            location.href = url;
          }
        });
      },
    };
  }

  function buildTimeline(resumed) {
    const online = Study.config.online;
    const session = Study.config.session;
    const timeline = [{ type: StartPlugin, resumed }];
    if (online.level_setting && !Study.state.level_done) timeline.push({ type: LevelPlugin });
    for (const test of ['antiphase', 'huggins']) {
      if (!online[test]) continue;
      const done = Study.state.screening[test];
      if (done) { if (!done.passed) Study.screeningFailed = true; continue; }
      timeline.push(...screeningNodes(test));
    }
    timeline.push(failScreeningScreen());

    const answered = new Set(Study.state.answered);
    const remaining = Study.plan.filter((t) => !answered.has(t.position));
    let previous = null;
    let sinceBreak = 0;
    remaining.forEach((t, i) => {
      const blockStart = !previous || previous.phase !== t.phase || previous.block !== t.block;
      if (blockStart) preloadNodes(remaining.slice(i).filter((u) => u.phase === t.phase && u.block === t.block)).forEach((n) => timeline.push(n));
      if (!previous) {
        let message = session.instructions;
        if (t.phase !== 'warmup' && phaseText(t.phase) !== session.instructions) message += '\n\n' + phaseText(t.phase);
        timeline.push(textScreen(message, T('web', 'begin')));
        sinceBreak = 0;
      } else if (t.phase !== previous.phase) {
        timeline.push(textScreen(phaseText(t.phase), T('web', 'begin')));
        sinceBreak = 0;
      } else if ((t.phase === 'test' && t.block !== previous.block) || (session.break_every > 0 && sinceBreak >= session.break_every)) {
        timeline.push(textScreen(session.break_text));
        sinceBreak = 0;
      }
      timeline.push({ type: TrialPlugin, trial: t });
      sinceBreak++;
      previous = t;
    });
    timeline.push(endNode());
    return timeline;
  }

  function showError(message) {
    document.body.innerHTML = `<div class="jspsych-display-element"><div class="jspsych-content-wrapper"><div class="jspsych-content">` +
      `<div class="avsi-text avsi-error">${escapeHtml(message)}</div></div></div></div>`;
  }

  async function start() {
    try {
      Study.jatos = typeof jatos !== 'undefined' && typeof jatos.appendResultData === 'function' && !!jatos.studyResultId;
      const response = await fetch('study.json');
      // English: the study's texts come in study.json itself.
      if (!response.ok) throw new Error(`The study's settings (study.json) could not be loaded (HTTP ${response.status}).`);
      Study.config = await response.json();
      Study.subject = await resolveSubject();
      Study.plan = Study.config.subjects[String(Study.subject)];
      Study.state = loadState();
      Study.otherRun = await claimRun();
      const resumed = Study.state.answered.length > 0 || Study.state.level_done || Object.keys(Study.state.screening).length > 0;
      Study.jsPsych = initJsPsych({ use_webaudio: true });
      // jsPsych's data starts empty on every page load: carry the earlier
      // page loads' records over, so its JSON export holds the whole session.
      for (const record of Study.state.log) Study.jsPsych.data.get().push(Object.assign({ trial_type: 'avsi-earlier-page' }, record));
      Study.jsPsych.run(buildTimeline(resumed));
      kickSender();
    } catch (e) {
      showError(e.message || String(e));
      console.error(e);
    }
  }

  // For the experimenter's console and the automated browser test.
  window.avsiStudy = {
    get subject() { return Study.subject; },
    get currentPosition() { return Study.currentPosition; },
    get answered() { return Study.state ? Study.state.answered.slice() : []; },
    get outbox() { return Study.state ? Study.state.outbox.length : 0; },
    get sendRequests() { return Sender.requests; },
    get run() { return Study.state ? Study.state.run : ''; },
    screeningAnswer: (test, index) => screeningTrial(test, index).answer,
    resultsText: () => (Study.state ? resultsText() : ''),
    jsPsychData: () => (Study.jsPsych ? Study.jsPsych.data.get().json() : '[]'),
  };

  if (typeof jatos !== 'undefined' && typeof jatos.onLoad === 'function') jatos.onLoad(start);
  else if (document.readyState === 'loading') document.addEventListener('DOMContentLoaded', start);
  else start();
})();
