// The result sender under a real 2-minute outage (headless Chromium, the
// study's real retry waits, no shortened parameter): the results endpoint
// answers 501 to every POST for OUTAGE_MS from the page load while a scripted
// participant does the whole study (with a reload in the middle and one click
// on Finish, which must offer the download), then recovers. Checks: never
// more than one request in flight; in every 60-s window of the outage at most
// BOUND_PER_MINUTE POSTs (the sender's worst case, below); after recovery
// every record the browser made arrives, and import-web stores every trial.
//
//   node tests/web/outage_e2e.mjs --avsi build/cli/avsi --work build/tests/web/outage_e2e [--chromium /usr/bin/chromium]
//
// Exit codes: 0 all checks passed, 1 a check failed, 77 skipped.
import fs from 'node:fs';
import path from 'node:path';
import {
  avsiRunner, check, finish, jsonLines, launchChromium, loadPuppeteer, parseArgs, prepareStudy, protocol, readCsv,
  scriptedParticipant, serveStudy, source,
} from './harness.mjs';

const OUTAGE_MS = 120000;
// Worst case of the sender (web/src/avsi-study.js): the n-th failure in a row
// waits at least half of min(60 s, 3 s * 2^(n-1)): 1.5, 3, 6, 12, 24, 30, 30 …
// s, so at most 6 automatic attempts fall in the first minute of failures
// (at 0, 1.5, 4.5, 10.5, 22.5 and 46.5 s) and at most 3 in any later one;
// one more for the participant's click on Finish, one more for a request cut
// by the reload (its failure is never seen, so the new page may send at once).
const BOUND_PER_MINUTE = 8;
const RESPONSE_DELAY_MS = 300;   // each answer is delayed, so overlapping requests would be seen

const args = parseArgs(process.argv.slice(2));
const avsi = path.resolve(args.avsi || path.join(source, 'build/cli/avsi'));
const work = path.resolve(args.work || path.join(source, 'build/tests/web/outage_e2e'));
const chromium = args.chromium || '/usr/bin/chromium';
const puppeteer = loadPuppeteer(chromium);
const { runLog } = avsiRunner(avsi);

const started = Date.now();
const { stimuli, study, config } = prepareStudy(avsi, work, 1);
const plan = config.subjects['1'];

let outageUntil = Infinity;         // set at the page load
const posts = [];                   // { at_ms, status }
const delivered = [];               // bodies answered 204
let open = 0;
let maxOpen = 0;
let completed = null;
const { base, close } = await serveStudy(study, {
  '/results': (req, res, body) => {
    const at = Date.now();
    open++;
    maxOpen = Math.max(maxOpen, open);
    const failing = at < outageUntil;
    posts.push({ at_ms: at, status: failing ? 501 : 204 });
    setTimeout(() => {
      open--;
      if (failing) { res.writeHead(501); res.end('outage'); return; }
      delivered.push(body);
      res.writeHead(204);
      res.end();
    }, RESPONSE_DELAY_MS);
  },
  '/complete': (req, res, body, url) => { completed = url.search; res.writeHead(200, { 'Content-Type': 'text/html' }); res.end('<p>complete</p>'); },
});

const browser = await launchChromium(puppeteer, chromium, path.join(work, 'profile'));
const typed = {};
let downloadText = '';
let outageStart = 0;
try {
  const page = await browser.newPage();
  const pageErrors = [];
  page.on('pageerror', (e) => pageErrors.push(String(e)));
  page.setDefaultTimeout(30000);
  const { clickButton, answer, screening } = scriptedParticipant(page, typed);
  outageStart = Date.now();
  outageUntil = outageStart + OUTAGE_MS;
  await page.goto(`${base}/index.html?subject=1`);
  await clickButton('Start');
  await clickButton('The level is comfortable');
  await screening('antiphase', 3);
  await screening('huggins', 3);
  await clickButton('Begin');
  await answer(1, 'the sun is warm');
  await clickButton('Begin');
  await page.waitForFunction(() => window.avsiStudy.currentPosition === 2 && document.querySelector('video'));
  const queuedBefore = await page.evaluate(() => window.avsiStudy.outbox);
  await page.reload();
  // The Start screen comes after the study has read its saved state.
  await page.waitForFunction(() => [...document.querySelectorAll('button')].some((b) => b.textContent === 'Start'));
  const queuedAfter = await page.evaluate(() => window.avsiStudy.outbox);
  check(queuedBefore > 0 && queuedAfter === queuedBefore, 'the unsent records survive the reload (the outbox is kept in localStorage)', `${queuedBefore} before, ${queuedAfter} after`);
  await clickButton('Start');
  await clickButton('Begin');
  await answer(2, 'she opened the door');
  await clickButton('Continue');
  await clickButton('Begin');
  await answer(3, 'the dog barked');
  await clickButton('Continue');
  await answer(4, 'he bought bread');
  await page.waitForFunction(() => document.querySelector('#avsi-finish'));
  // Finish during the outage: the answers cannot be sent; the download is offered.
  await clickButton('Finish');
  await page.waitForFunction(() => [...document.querySelectorAll('button')].some((b) => b.textContent === 'Download results'), { timeout: 40000 });
  const status = await page.evaluate(() => document.querySelector('#avsi-end-status').textContent);
  check(/could not all be sent/.test(status), 'Finish during the outage says the answers could not be sent and offers "Download results"', status);
  downloadText = await page.evaluate(() => window.avsiStudy.resultsText());
  check(Date.now() < outageUntil, 'the participant finished within the outage', `${((Date.now() - outageStart) / 1000).toFixed(1)} s after the page load`);

  // The rest of the outage, then recovery: everything must arrive.
  await new Promise((resolve) => setTimeout(resolve, Math.max(0, outageUntil - Date.now())));
  await page.waitForFunction(() => window.avsiStudy.outbox === 0, { timeout: 90000, polling: 500 });
  const recoveredAfter = (Date.now() - outageUntil) / 1000;
  check(true, `the outbox emptied ${recoveredAfter.toFixed(1)} s after the server recovered`);
  check(pageErrors.length === 0, 'no page errors', pageErrors.join('; '));
  await clickButton('Finish');
  await page.waitForFunction(() => location.pathname === '/complete', { timeout: 30000 });
  check(completed === '?cc=TEST42', 'after recovery Finish goes to the completion URL', completed);
} finally {
  await browser.close();
  close();
}

// Requests during the outage.
const failedPosts = posts.filter((p) => p.status === 501);
let worst = 0;
let worstAt = 0;
for (const p of failedPosts) {
  const inWindow = failedPosts.filter((q) => q.at_ms >= p.at_ms && q.at_ms < p.at_ms + 60000).length;
  if (inWindow > worst) { worst = inWindow; worstAt = p.at_ms; }
}
const perMinute = [0, 1].map((m) => failedPosts.filter((p) => p.at_ms >= outageStart + m * 60000 && p.at_ms < outageStart + (m + 1) * 60000).length);
console.log(`# outage ${OUTAGE_MS / 1000} s: ${failedPosts.length} failed POSTs (minute 1: ${perMinute[0]}, minute 2: ${perMinute[1]}); ` +
  `worst 60-s window ${worst} (from ${((worstAt - outageStart) / 1000).toFixed(1)} s); POST times (s): ` +
  failedPosts.map((p) => ((p.at_ms - outageStart) / 1000).toFixed(1)).join(' '));
check(failedPosts.length > 0 && worst <= BOUND_PER_MINUTE, `at most ${BOUND_PER_MINUTE} POSTs in every 60-s window of the 2-minute outage`, `worst window ${worst}`);
check(failedPosts.some((p) => p.at_ms > outageUntil - 60000), 'the sender kept trying in the outage\'s last minute');
check(maxOpen === 1, 'never more than one request in flight', `max ${maxOpen}`);

// Every record arrived once the server recovered.
const sent = jsonLines(delivered.join(''));
const made = jsonLines(downloadText);
const key = (r) => `${r.run}/${r.seq}`;
const sentKeys = new Set(sent.map(key));
const missing = made.filter((r) => !sentKeys.has(key(r)));
check(made.length > 0 && missing.length === 0, `every record arrived after the outage (${made.length} made during it, ${sent.length} delivered)`,
  missing.map(key).join(', '));
const resultsFile = path.join(work, 'results.jsonl');
fs.writeFileSync(resultsFile, delivered.join(''));
const importLog = runLog('import-web', resultsFile, '--protocol', protocol, '--db', path.join(work, 'study.sqlite'), '--stimuli', stimuli);
check(new RegExp(`${plan.length} trials added`).test(importLog), `import-web stores the ${plan.length} trials`, importLog.trim().split('\n').pop());
const { run } = avsiRunner(avsi);
run('export', path.join(work, 'study.sqlite'), '--out', path.join(work, 'export'));
const responses = readCsv(path.join(work, 'export', 'responses.csv'));
check(plan.every((t) => responses.some((r) => Number(r.trial) === t.position && r.response === typed[t.position])), 'the stored answers are the typed ones');
finish('outage e2e', started);
