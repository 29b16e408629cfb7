// End-to-end test of the online study in a real headless browser (Debian's
// chromium driven by puppeteer-core from web/node_modules): build the test
// protocol's stimuli, design the lists, `avsi export-web`, serve the study
// from a local static server (node's http module; POST /results collects
// the records), and let a scripted participant do the start screen, level
// setting, both headphone checks, warm-up, practice (with a reload in the
// middle: the study must resume at the first unanswered trial) and two short
// test blocks with typed answers; then `avsi import-web`, `export`, `score`
// and `analyze`, checking the stored answers, timing rows and scores against
// what was typed.
//
//   node tests/web/study_e2e.mjs --avsi build/cli/avsi --work build/tests/web/study_e2e [--chromium /usr/bin/chromium]
//
// Exit codes: 0 all checks passed, 1 a check failed, 77 skipped (no
// chromium or puppeteer-core installed; scripts/install-deps installs both).
import { execFileSync, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import { createRequire } from 'node:module';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

import { readCsv } from './harness.mjs';

const here = path.dirname(fileURLToPath(import.meta.url));
const source = path.resolve(here, '..', '..');
const args = Object.fromEntries(process.argv.slice(2).reduce((pairs, a, i, all) => (a.startsWith('--') ? [...pairs, [a.slice(2), all[i + 1]]] : pairs), []));
const avsi = path.resolve(args.avsi || path.join(source, 'build/cli/avsi'));
const work = path.resolve(args.work || path.join(source, 'build/tests/web/study_e2e'));
const chromium = args.chromium || '/usr/bin/chromium';
const protocol = path.join(source, 'tests/data/web/protocol.toml');
const corpus = path.join(source, 'tests/data/experiment/built/corpus.csv');

let passed = 0;
let failed = 0;
function check(condition, what, detail) {
  if (condition) { passed++; console.log(`ok - ${what}`); } else { failed++; console.log(`not ok - ${what}${detail !== undefined ? `: ${detail}` : ''}`); }
  return condition;
}
function skip(why) { console.log(`skipped: ${why}`); process.exit(77); }

if (!fs.existsSync(chromium)) skip(`${chromium} is not installed (scripts/install-deps installs Debian's chromium)`);
let puppeteer;
try {
  puppeteer = createRequire(path.join(source, 'web', 'package.json'))('puppeteer-core');
} catch (e) {
  skip('puppeteer-core is not installed in web/node_modules (scripts/install-deps runs npm ci there)');
}

function run(...argv) {
  return execFileSync(avsi, argv, { encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] });
}
// Runs avsi expecting success; returns what it logged (stderr).
function runLog(...argv) {
  const r = spawnSync(avsi, argv, { encoding: 'utf8' });
  if (r.status !== 0) throw new Error(`avsi ${argv.join(' ')} failed (${r.status}): ${r.stderr}`);
  return r.stderr;
}
function runFails(...argv) {
  try { execFileSync(avsi, argv, { encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] }); return null; } catch (e) { return { status: e.status, stderr: String(e.stderr) }; }
}

const started = Date.now();
fs.rmSync(work, { recursive: true, force: true });
fs.mkdirSync(work, { recursive: true });
const stimuli = path.join(work, 'stimuli');
const lists = path.join(work, 'lists.csv');
const study = path.join(work, 'study');
run('build-stimuli', protocol, '--out', stimuli);
run('design', protocol, '--subjects', '2', '--out', lists);
run('export-web', protocol, '--stimuli', stimuli, '--lists', lists, '--out', study);
check(fs.existsSync(path.join(study, 'index.html')) && fs.existsSync(path.join(work, 'study.jzip')), 'export-web wrote the study folder and the .jzip');
const config = JSON.parse(fs.readFileSync(path.join(study, 'study.json'), 'utf8'));
const plan = config.subjects['1'];

// The static server: the study folder, POST /results, GET /complete.
const posted = [];
let completed = null;
const types = { '.html': 'text/html', '.js': 'text/javascript', '.css': 'text/css', '.json': 'application/json', '.mp4': 'video/mp4', '.wav': 'audio/wav' };
// A stand-in for JATOS' jatos.js and server (the API calls the study makes:
// onLoad, appendResultData, study-session data, batch session, end), so the
// JATOS code paths run: subject allocation from the batch session, records
// through appendResultData, resume from study-session data alone.
const jatos = { results: '', session: {}, batch: {} };
const jatosStub = `window.jatos = (function () {
  const j = { studyResultId: 5, workerId: 17, urlQueryParameters: Object.fromEntries(new URLSearchParams(location.search)), studySessionData: {} };
  let batch = {};
  const post = (p, body) => fetch(p, { method: 'POST', body: JSON.stringify(body) }).then((r) => { if (!r.ok) throw new Error(String(r.status)); return r.json(); });
  j.onLoad = (cb) => { Promise.all([fetch('/jatos/session').then((r) => r.json()), fetch('/jatos/batch').then((r) => r.json())]).then(([s, b]) => { j.studySessionData = s; batch = b; cb(); }); };
  j.appendResultData = (text) => post('/jatos/append', { text });
  j.setStudySessionData = (data) => post('/jatos/session', data);
  j.batchSession = { getAll: () => batch, get: (k) => batch[k], set: (k, v) => post('/jatos/batch', { key: k, value: v }).then((b) => { batch = b; }) };
  j.endStudyAndRedirect = (url) => { location.href = url; };
  j.endStudy = () => {};
  return j;
})();`;
let serveJatos = false;
const server = http.createServer((req, res) => {
  const url = new URL(req.url, 'http://localhost');
  if (url.pathname === '/jatos.js' && serveJatos) { res.writeHead(200, { 'Content-Type': 'text/javascript' }); res.end(jatosStub); return; }
  if (url.pathname.startsWith('/jatos/')) {
    let body = '';
    req.on('data', (chunk) => { body += chunk; });
    req.on('end', () => {
      const what = url.pathname.slice(7);
      if (req.method === 'POST' && what === 'append') jatos.results += JSON.parse(body).text;
      if (req.method === 'POST' && what === 'session') jatos.session = JSON.parse(body);
      if (req.method === 'POST' && what === 'batch') { const { key, value } = JSON.parse(body); jatos.batch[key] = value; }
      res.writeHead(200, { 'Content-Type': 'application/json' });
      res.end(JSON.stringify(what === 'session' ? jatos.session : what === 'batch' ? jatos.batch : {}));
    });
    return;
  }
  if (req.method === 'POST' && url.pathname === '/results') {
    let body = '';
    req.on('data', (chunk) => { body += chunk; });
    req.on('end', () => { posted.push(body); res.writeHead(204); res.end(); });
    return;
  }
  if (url.pathname === '/complete') { completed = url.search; res.writeHead(200, { 'Content-Type': 'text/html' }); res.end('<p>complete</p>'); return; }
  const file = path.join(study, path.normalize(decodeURIComponent(url.pathname)).replace(/^(\.\.[/\\])+/, ''));
  if (!file.startsWith(study) || !fs.existsSync(file) || fs.statSync(file).isDirectory()) { res.writeHead(404); res.end(); return; }
  res.writeHead(200, { 'Content-Type': types[path.extname(file)] || 'application/octet-stream' });
  res.end(fs.readFileSync(file));
});
await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));
const base = `http://127.0.0.1:${server.address().port}`;

const browser = await puppeteer.launch({
  executablePath: chromium,
  headless: true,
  // Chromium's default autoplay policy: the Start click (a real input event) starts the sound.
  args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--no-first-run', `--user-data-dir=${path.join(work, 'profile')}`],
});
const typed = {};
const jatosTyped = {};
let downloadText = '';
let jsPsychJson = '';
// A scripted participant's helpers on one page.
function participant(page, typed) {
  // Helpers: click a button by its text once it is enabled; wait for the answer box.
  const clickButton = async (text) => {
    const handle = await page.waitForFunction((t) => [...document.querySelectorAll('button')].find((b) => b.textContent.trim() === t && !b.disabled), {}, text);
    await handle.click();
  };
  const answer = async (position, text, options = {}) => {
    await page.waitForFunction((p) => window.avsiStudy.currentPosition === p && document.querySelector('#avsi-answer'), {}, position);
    if (options.emptyFirst) {
      await page.focus('#avsi-answer');
      await page.keyboard.press('Enter');
      await page.waitForFunction(() => document.body.textContent.includes('Submit an empty answer?'));
      await page.keyboard.press('n');
      await page.waitForSelector('#avsi-answer');
    }
    if (text === '') {
      await page.focus('#avsi-answer');
      await page.keyboard.press('Enter');
      await page.waitForFunction(() => document.body.textContent.includes('Submit an empty answer?'));
      await page.keyboard.press('y');
    } else {
      await page.type('#avsi-answer', text);
      await page.keyboard.press('Enter');
    }
    typed[position] = text;
  };
  const screening = async (test, trials, wrong) => {
    await clickButton('Begin');
    for (let i = 1; i <= trials; i++) {
      await page.waitForFunction((n) => document.body.textContent.includes(`Sound check ${n} of`) && [...document.querySelectorAll('button')].some((b) => b.textContent === '1' && !b.disabled), {}, i);
      const correct = await page.evaluate((t, n) => window.avsiStudy.screeningAnswer(t, n), test, i);
      const choice = wrong.includes(i) ? (correct % 3) + 1 : correct;
      await clickButton(String(choice));
    }
  };

  return { clickButton, answer, screening };
}

try {
  const page = await browser.newPage();
  const pageErrors = [];
  page.on('pageerror', (e) => pageErrors.push(String(e)));
  page.setDefaultTimeout(20000);
  const { clickButton, answer, screening } = participant(page, typed);
  await page.goto(`${base}/index.html?subject=1`);
  await clickButton('Start');
  await clickButton('The level is comfortable');
  await screening('antiphase', 3, [3]);  // 2 of 3 correct: passes (antiphase_pass = 2)
  await screening('huggins', 3, []);
  await clickButton('Begin');                                  // instructions
  await answer(1, 'the sun is warm');                          // warm-up
  await clickButton('Begin');                                  // practice instructions
  await page.waitForFunction(() => window.avsiStudy.currentPosition === 2 && document.querySelector('video'));

  // Reload in the middle of the practice trial: the study resumes at trial 2.
  const answeredBefore = await page.evaluate(() => window.avsiStudy.answered);
  await page.reload();
  await clickButton('Start');
  await clickButton('Begin');
  await page.waitForFunction(() => window.avsiStudy.currentPosition > 0);
  const resumedAt = await page.evaluate(() => window.avsiStudy.currentPosition);
  check(JSON.stringify(answeredBefore) === '[1]' && resumedAt === 2, 'a reload during trial 2 resumes at trial 2, the first unanswered', `answered ${JSON.stringify(answeredBefore)}, resumed at ${resumedAt}`);
  const levelAgain = await page.evaluate(() => document.body.textContent.includes('steady noise'));
  check(!levelAgain, 'the resumed session skips the level setting and screening already done');

  await answer(2, 'she opened a door', { emptyFirst: true });   // practice; "no" to the empty answer first
  await page.waitForFunction(() => document.body.textContent.includes('The sentence was:'));
  const feedback = await page.evaluate(() => document.body.textContent);
  check(feedback.includes('She opened the door.'), 'practice feedback shows the sentence text');
  await clickButton('Continue');
  await clickButton('Begin');                                  // test instructions
  await answer(3, '');                                          // an empty answer, confirmed
  await clickButton('Continue');                               // break between test blocks
  // Letters of other languages typed into the answer box (å ä ö ü ß) are stored as typed.
  await answer(4, 'he bought bread: får åtta äpplen, süße Brötchen');
  await page.waitForFunction(() => document.querySelector('#avsi-finish'));
  downloadText = await page.evaluate(() => window.avsiStudy.resultsText());
  jsPsychJson = await page.evaluate(() => window.avsiStudy.jsPsychData());
  await page.waitForFunction(() => window.avsiStudy.outbox === 0);
  await clickButton('Finish');
  await page.waitForFunction(() => location.pathname === '/complete', { timeout: 30000 });
  check(completed === '?cc=TEST42', 'Finish sends the participant to the protocol\'s completion URL', completed);
  check(pageErrors.length === 0, 'no page errors', pageErrors.join('; '));

  // The same study under (a stand-in for) JATOS: no ?subject, a fresh profile.
  serveJatos = true;
  const context = await browser.createBrowserContext();
  const jpage = await context.newPage();
  jpage.setDefaultTimeout(20000);
  const j = participant(jpage, jatosTyped);
  await jpage.goto(`${base}/index.html`);
  await j.clickButton('Start');
  await j.clickButton('The level is comfortable');
  await j.screening('antiphase', 3, []);
  await j.screening('huggins', 3, [1, 2]);  // 1 of 3: fails, recorded, the session goes on
  await j.clickButton('Begin');
  await j.answer(1, 'sun warm');
  await jpage.waitForFunction(() => window.avsiStudy.outbox === 0);
  const allocated = await jpage.evaluate(() => window.avsiStudy.subject);
  check(allocated === 1 && jatos.batch.avsi_worker_17 === 1 && jatos.batch.avsi_subject_1 === 17,
    'under JATOS the worker gets the lowest free subject from the batch session', JSON.stringify(jatos.batch));
  // Only JATOS' study-session data survives: localStorage is cleared before the reload.
  await jpage.evaluate(() => localStorage.clear());
  await jpage.reload();
  await j.clickButton('Start');
  await j.clickButton('Begin');
  await jpage.waitForFunction(() => window.avsiStudy.currentPosition > 0);
  check(await jpage.evaluate(() => window.avsiStudy.currentPosition) === 2, 'with localStorage cleared, JATOS study-session data resumes at trial 2');
  await j.answer(2, 'she opened the door');
  await j.clickButton('Continue');
  await j.clickButton('Begin');
  await j.answer(3, 'the dog barked');
  await j.clickButton('Continue');
  await j.answer(4, 'bought bread');
  await jpage.waitForFunction(() => window.avsiStudy.outbox === 0);
  completed = null;
  await j.clickButton('Finish');
  await jpage.waitForFunction(() => location.pathname === '/complete', { timeout: 30000 });
  check(completed === '?cc=TEST42', 'under JATOS, Finish ends the study with the completion URL');
  await context.close();
} finally {
  await browser.close();
  server.close();
}

// What the browser sent.
const postedText = posted.join('');
fs.writeFileSync(path.join(work, 'results.jsonl'), postedText);
fs.writeFileSync(path.join(work, 'download.jsonl'), downloadText);
fs.writeFileSync(path.join(work, 'jspsych.json'), jsPsychJson);
const records = postedText.trim().split('\n').map((l) => JSON.parse(l));
const seqs = (rs) => rs.map((r) => r.seq).sort((a, b) => a - b).join(',');
const downloaded = downloadText.trim().split('\n').map((l) => JSON.parse(l));
check(records.length > 0 && seqs(records.filter((r) => r.avsi !== 'end')) === seqs(downloaded.filter((r) => r.avsi !== 'end')), 'every record was POSTed and is in the download', `${records.length} posted, ${downloaded.length} downloaded`);
check(new Set(records.map((r) => r.session)).size === 2, 'two browser sessions (before and after the reload)');

// Back into the pipeline.
const db = path.join(work, 'study.sqlite');
const importLog = runLog('import-web', path.join(work, 'results.jsonl'), '--protocol', protocol, '--db', db, '--stimuli', stimuli);
check(/4 trials added, 0 already stored/.test(importLog), 'import-web adds the 4 trials', importLog.trim().split('\n').pop());
run('export', db, '--out', path.join(work, 'export'));
const responses = readCsv(path.join(work, 'export', 'responses.csv'));
check(responses.length === plan.length, `import-web stored ${plan.length} responses`, responses.length);
for (const t of plan) {
  const row = responses.find((r) => Number(r.trial) === t.position);
  check(row && row.response === typed[t.position] && row.condition === t.condition && row.sentence === t.sentence && row.mode === 'online',
    `trial ${t.position}: the stored answer is the typed one ("${typed[t.position]}"), ${t.condition} ${t.sentence}, online`, row && JSON.stringify(row));
}
check(responses.find((r) => Number(r.trial) === 3).confirmed_empty === '1', 'the confirmed empty answer is marked');
const timing = readCsv(path.join(work, 'export', 'timing.csv'));
const frames = readCsv(path.join(work, 'export', 'frames.csv'));
check(timing.length === plan.length, 'a timing row for every trial', timing.length);
for (const row of timing) {
  const stim = config.stimuli[plan[Number(row.trial) - 1].stimulus];
  const shown = Number(row.frames_shown);
  check(Number(row.frames_total) === stim.frames && shown > 0 && Number(row.dropped_frames) === stim.frames - shown && Number(row.refresh_hz) > 0,
    `trial ${row.trial}: timing row (${shown} of ${row.frames_total} frames shown, ${row.dropped_frames} dropped, mean A/V offset ${row.mean_av_offset_ms} ms, refresh ${row.refresh_hz} Hz)`);
  check(frames.filter((f) => f.trial === row.trial).length === shown, `trial ${row.trial}: one frames row per frame shown`);
}
const web = readCsv(path.join(work, 'export', 'web_timing.csv'));
check(web.length === plan.length && web.every((w) => w.frame_callbacks === '1'), 'browser timing (requestVideoFrameCallback) for every trial');
const screening = readCsv(path.join(work, 'export', 'screening.csv'));
const antiphase = screening.find((s) => s.test === 'antiphase');
const huggins = screening.find((s) => s.test === 'huggins');
check(antiphase && antiphase.correct === '2' && antiphase.passed === '1' && huggins && huggins.correct === '3' && huggins.passed === '1',
  'screening: antiphase 2 of 3 (passed), Huggins 3 of 3 (passed)', JSON.stringify(screening));
const sessions = readCsv(path.join(work, 'export', 'sessions.csv'));
check(sessions.length === 2 && sessions.every((s) => s.mode === 'online') && sessions.some((s) => s.end_reason === 'completed'),
  'two online sessions, the second completed', JSON.stringify(sessions.map((s) => [s.mode, s.end_reason])));

// Scoring and analysis, unchanged.
run('score', '--corpus', corpus, '--responses', path.join(work, 'export', 'responses.csv'), '--out', path.join(work, 'scores'));
const scores = readCsv(path.join(work, 'scores', 'scores.csv'));
const byCondition = Object.fromEntries(scores.filter((s) => s.subject === '1').map((s) => [s.condition, Number(s.percent)]));
const testTrials = plan.filter((t) => t.phase === 'test');
const expected = Object.fromEntries(testTrials.map((t) => [t.condition, typed[t.position] === '' ? 0 : 100]));
check(Object.keys(expected).every((c) => byCondition[c] === expected[c]), 'score: keyword percentages match the typed answers', `${JSON.stringify(byCondition)} vs ${JSON.stringify(expected)}`);
run('analyze', path.join(work, 'scores', 'scores.csv'), '--out', path.join(work, 'report'), '--protocol', protocol);
check(fs.existsSync(path.join(work, 'report', 'report.md')), 'analyze wrote its report');

// A second import of the same results changes nothing; the jsPsych JSON and the download give the same answers.
const again = runLog('import-web', path.join(work, 'results.jsonl'), '--protocol', protocol, '--db', db, '--stimuli', stimuli);
check(/0 browser sessions added, 0 trials added, 4 already stored/.test(again), 'a repeated import adds nothing', again.trim().split('\n').pop());
for (const [name, file] of [['jsPsych JSON', 'jspsych.json'], ['download', 'download.jsonl']]) {
  const other = path.join(work, `${file}.sqlite`);
  run('import-web', path.join(work, file), '--protocol', protocol, '--db', other, '--stimuli', study);
  run('export', other, '--out', path.join(work, `${file}-export`));
  const rows = readCsv(path.join(work, `${file}-export`, 'responses.csv'));
  check(rows.length === plan.length && rows.every((r) => r.response === typed[Number(r.trial)]), `the ${name} imports to the same answers`);
}
// JATOS' "data only" export is the appended lines: import them.
fs.writeFileSync(path.join(work, 'jatos_results.txt'), jatos.results);
const jatosDb = path.join(work, 'jatos.sqlite');
runLog('import-web', path.join(work, 'jatos_results.txt'), '--protocol', protocol, '--db', jatosDb, '--stimuli', stimuli);
run('export', jatosDb, '--out', path.join(work, 'jatos-export'));
const jatosRows = readCsv(path.join(work, 'jatos-export', 'responses.csv'));
check(jatosRows.length === plan.length && jatosRows.every((r) => r.subject === '1' && r.response === jatosTyped[Number(r.trial)]),
  'the JATOS results import to the typed answers', JSON.stringify(jatosRows.map((r) => r.response)));
const jatosScreening = readCsv(path.join(work, 'jatos-export', 'screening.csv'));
check(jatosScreening.some((r) => r.test === 'huggins' && r.correct === '1' && r.passed === '0'), 'the failed Huggins check is recorded, the subject kept');

// A truncated file is refused and the database is unchanged.
const truncated = path.join(work, 'truncated.jsonl');
fs.writeFileSync(truncated, postedText.slice(0, Math.floor(postedText.length * 0.6)));
const before = fs.readFileSync(path.join(work, 'export', 'responses.csv'), 'utf8');
const refused = runFails('import-web', truncated, '--protocol', protocol, '--db', db, '--stimuli', stimuli);
run('export', db, '--out', path.join(work, 'export-after'));
check(refused && refused.status === 1 && /truncated\.jsonl:\d+:\d+: error: .*truncated or damaged/.test(refused.stderr) &&
  fs.readFileSync(path.join(work, 'export-after', 'responses.csv'), 'utf8') === before,
  'a truncated results file is refused (file:line:col) and the database is unchanged', refused && refused.stderr.trim());

console.log(`web study e2e: ${((Date.now() - started) / 1000).toFixed(1)} s`);
console.log(`${passed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
