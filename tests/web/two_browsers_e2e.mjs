// One subject in two browsers (headless Chromium, two browser contexts with
// their own localStorage): browser A takes subject 1 to the end; browser B
// opens the same link later, is warned on the Start screen that a second
// browser begins again, and answers the first 2 trials with the same words.
// Then `avsi import-web` of the collected records: refused without a rule
// (naming both runs), and with each `--runs` rule one run kept and the other
// reported; importing the other run afterwards finds the same answers
// already stored (compared by text, never called different). A third
// browser, under a stand-in for jatos.js whose batch session already holds
// another run's claim on subject 1, warns on its Start screen and records
// the other run in its session record.
//
//   node tests/web/two_browsers_e2e.mjs --avsi build/cli/avsi --work build/tests/web/two_browsers [--chromium /usr/bin/chromium]
//
// Exit codes: 0 all checks passed, 1 a check failed, 77 skipped.
import fs from 'node:fs';
import path from 'node:path';
import {
  avsiRunner, check, finish, jsonLines, launchChromium, loadPuppeteer, parseArgs, prepareStudy, protocol, readCsv,
  scriptedParticipant, serveStudy, source,
} from './harness.mjs';

const args = parseArgs(process.argv.slice(2));
const avsi = path.resolve(args.avsi || path.join(source, 'build/cli/avsi'));
const work = path.resolve(args.work || path.join(source, 'build/tests/web/two_browsers'));
const chromium = args.chromium || '/usr/bin/chromium';
const puppeteer = loadPuppeteer(chromium);
const { run, runLog, runFails } = avsiRunner(avsi);

const started = Date.now();
const { stimuli, study, config } = prepareStudy(avsi, work, 1);
const plan = config.subjects['1'];
const words = { 1: 'the sun is warm', 2: 'she opened the door', 3: 'the dog barked', 4: 'he bought bread' };

const posted = [];
// Under (a stand-in for) JATOS, the third browser finds subject 1 claimed by
// another run in the batch session (avsi_run_1) and must say so.
let serveJatos = false;
const jatosBatch = { avsi_run_1: 'run-of-another-browser' };
const jatosAppended = [];
const jatosStub = `window.jatos = (function () {
  const j = { studyResultId: 9, workerId: 23, urlQueryParameters: Object.fromEntries(new URLSearchParams(location.search)), studySessionData: {} };
  let batch = ${JSON.stringify(jatosBatch)};
  j.onLoad = (cb) => setTimeout(cb, 0);
  j.appendResultData = (text) => fetch('/jatos/append', { method: 'POST', body: text }).then((r) => { if (!r.ok) throw new Error(String(r.status)); });
  j.setStudySessionData = () => Promise.resolve();
  j.batchSession = { getAll: () => batch, get: (k) => batch[k], set: (k, v) => { batch[k] = v; return Promise.resolve(); } };
  j.endStudy = () => {};
  return j;
})();`;
const { base, close } = await serveStudy(study, {
  '/results': (req, res, body) => { posted.push(body); res.writeHead(204); res.end(); },
  '/jatos.js': (req, res) => {
    if (!serveJatos) { res.writeHead(404); res.end(); return; }
    res.writeHead(200, { 'Content-Type': 'text/javascript' });
    res.end(jatosStub);
  },
  '/jatos/append': (req, res, body) => { jatosAppended.push(body); res.writeHead(200); res.end(); },
});
const browser = await launchChromium(puppeteer, chromium, path.join(work, 'profile'));
let warningB = '';
try {
  // Browser A: the whole study. Browser B: a fresh context (its own localStorage), 2 trials.
  for (const [name, trials] of [['A', 4], ['B', 2]]) {
    const context = await browser.createBrowserContext();
    const page = await context.newPage();
    page.setDefaultTimeout(20000);
    const typed = {};
    const { clickButton, answer, screening } = scriptedParticipant(page, typed);
    await page.goto(`${base}/index.html?subject=1`);
    await page.waitForFunction(() => [...document.querySelectorAll('button')].some((b) => b.textContent === 'Start'));
    if (name === 'B') warningB = await page.evaluate(() => document.body.innerText);
    await clickButton('Start');
    await clickButton('The level is comfortable');
    await screening('antiphase', 3);
    await screening('huggins', 3);
    await clickButton('Begin');
    await answer(1, words[1]);
    await clickButton('Begin');
    await answer(2, words[2]);
    if (trials > 2) {
      await clickButton('Continue');
      await clickButton('Begin');
      await answer(3, words[3]);
      await clickButton('Continue');
      await answer(4, words[4]);
    }
    await page.waitForFunction(() => window.avsiStudy.outbox === 0);
    await context.close();
  }
  // A third browser under JATOS, where the batch session already holds another run's claim.
  serveJatos = true;
  const context = await browser.createBrowserContext();
  const page = await context.newPage();
  page.setDefaultTimeout(20000);
  const { clickButton } = scriptedParticipant(page, {});
  await page.goto(`${base}/index.html?subject=1`);
  await page.waitForFunction(() => [...document.querySelectorAll('button')].some((b) => b.textContent === 'Start'));
  const warningJatos = await page.evaluate(() => document.body.innerText);
  check(/This participant number was already started in another browser or on another device/.test(warningJatos),
    'under JATOS, a browser finding the subject claimed by another run in the batch session warns on Start', warningJatos.slice(0, 300));
  await clickButton('Start');
  await page.waitForFunction(() => document.body.textContent.includes('steady noise'));
  await page.waitForFunction(() => window.avsiStudy.outbox === 0);
  const session = jsonLines(jatosAppended.join('')).find((r) => r.avsi === 'session');
  check(session && session.other_run === 'run-of-another-browser', 'its session record names the other run (other_run)', session && JSON.stringify(session.other_run));
  await context.close();
} finally {
  await browser.close();
  close();
}
check(/If you already started this study in another browser or on another device, please continue there/.test(warningB),
  'the second browser\'s Start screen warns that it begins again at the first sentence');

const records = jsonLines(posted.join(''));
const runs = [...new Set(records.map((r) => r.run))];
check(runs.length === 2, 'the two browsers sent two runs of subject 1', runs.join(', '));
const sessionOf = (runId) => records.find((r) => r.run === runId && r.avsi === 'session').session;
const [runA, runB] = runs;
const results = path.join(work, 'results.jsonl');
fs.writeFileSync(results, posted.join(''));
const importArgs = (db) => ['import-web', results, '--protocol', protocol, '--db', path.join(work, db), '--stimuli', stimuli];

const refused = runFails(...importArgs('none.sqlite'));
check(refused && refused.status === 1 && refused.stderr.includes(`subject 1 took the study in 2 browser runs`) &&
  refused.stderr.includes(runA) && refused.stderr.includes(runB) && refused.stderr.includes('--runs first|last|most-complete|session=ID') &&
  !/different|differs/.test(refused.stderr),
  'without --runs the import is refused, naming both runs (no answer called different)', refused && refused.stderr.trim());

for (const [rule, kept, left, keptTrials, leftTrials] of [
  ['first', runA, runB, 4, 2], ['last', runB, runA, 2, 4], ['most-complete', runA, runB, 4, 2], [`session=${sessionOf(runB)}`, runB, runA, 2, 4]]) {
  const db = `${rule.split('=')[0]}.sqlite`;
  const log = runLog(...importArgs(db), '--runs', rule);
  check(new RegExp(`${keptTrials} trials added`).test(log) &&
    log.includes(`subject 1: run ${left} left out (started`) && log.includes(`${leftTrials} trials, sessions ${sessionOf(left)}); kept run ${kept} (${keptTrials} trials) by --runs ${rule}`),
    `--runs ${rule}: run ${kept === runA ? 'A' : 'B'} kept (${keptTrials} trials), run ${left === runA ? 'A' : 'B'} reported as left out`,
    log.trim().split('\n').filter((l) => /left out|trials added/.test(l)).join(' | '));
  run('export', path.join(work, db), '--out', path.join(work, `${db}-export`));
  const responses = readCsv(path.join(work, `${db}-export`, 'responses.csv'));
  check(responses.length === keptTrials && responses.every((r) => r.response === words[Number(r.trial)]), `--runs ${rule}: the kept run's answers are stored`);
  // The other run next: its answers are the same words, so they are found stored, not different.
  const other = rule === 'first' || rule === 'most-complete' ? 'last' : 'first';
  const again = runLog(...importArgs(db), '--runs', other);
  check(new RegExp(` ${keptTrials === 4 ? 0 : 2} trials added, 2 already stored;`).test(again),
    `--runs ${rule}, then --runs ${other} into the same database: identical answers are already stored, not different`, again.trim().split('\n').pop());
}
finish('two browsers e2e', started);
