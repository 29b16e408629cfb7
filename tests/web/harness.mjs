// Shared parts of the headless-browser tests of the online study: options,
// checks, running avsi, building and exporting the test protocol's study, a
// local static server for it (127.0.0.1 only), and starting Debian's
// chromium through puppeteer-core with the closed-network flags.
import { execFileSync, spawnSync } from 'node:child_process';
import fs from 'node:fs';
import http from 'node:http';
import { createRequire } from 'node:module';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
export const source = path.resolve(here, '..', '..');
export const protocol = path.join(source, 'tests/data/web/protocol.toml');
export const corpus = path.join(source, 'tests/data/experiment/built/corpus.csv');

// `--name value` pairs and bare `--flag`s of the command line.
export function parseArgs(argv) {
  const out = {};
  for (let i = 0; i < argv.length; i++) {
    if (!argv[i].startsWith('--')) continue;
    const next = argv[i + 1];
    if (next === undefined || next.startsWith('--')) out[argv[i].slice(2)] = true;
    else { out[argv[i].slice(2)] = next; i++; }
  }
  return out;
}

let passed = 0;
let failed = 0;
// One TAP-like line per check; the script's exit code counts the failures.
export function check(condition, what, detail) {
  if (condition) { passed++; console.log(`ok - ${what}`); } else { failed++; console.log(`not ok - ${what}${detail !== undefined ? `: ${detail}` : ''}`); }
  return condition;
}
export function finish(name, started) {
  console.log(`${name}: ${((Date.now() - started) / 1000).toFixed(1)} s`);
  console.log(`${passed} passed, ${failed} failed`);
  process.exit(failed ? 1 : 0);
}
export function skip(why) { console.log(`skipped: ${why}`); process.exit(77); }

// puppeteer-core from web/node_modules, or exit 77 (skipped).
export function loadPuppeteer(chromium) {
  if (!fs.existsSync(chromium)) skip(`${chromium} is not installed (scripts/install-deps installs Debian's chromium)`);
  try {
    return createRequire(path.join(source, 'web', 'package.json'))('puppeteer-core');
  } catch (e) {
    return skip('puppeteer-core is not installed in web/node_modules (scripts/install-deps runs npm ci there)');
  }
}

export function avsiRunner(avsi) {
  return {
    run: (...argv) => execFileSync(avsi, argv, { encoding: 'utf8', stdio: ['ignore', 'pipe', 'pipe'] }),
    // Runs avsi expecting success; returns what it logged (stderr).
    runLog: (...argv) => {
      const r = spawnSync(avsi, argv, { encoding: 'utf8' });
      if (r.status !== 0) throw new Error(`avsi ${argv.join(' ')} failed (${r.status}): ${r.stderr}`);
      return r.stderr;
    },
    // Runs avsi expecting failure: { status, stderr }, or null if it succeeded.
    runFails: (...argv) => {
      const r = spawnSync(avsi, argv, { encoding: 'utf8' });
      return r.status === 0 ? null : { status: r.status, stderr: r.stderr };
    },
  };
}

// Builds the test protocol's stimuli, designs `subjects` subjects' lists and
// exports the study into `work`.
export function prepareStudy(avsi, work, subjects = 2) {
  const { run } = avsiRunner(avsi);
  fs.rmSync(work, { recursive: true, force: true });
  fs.mkdirSync(work, { recursive: true });
  const stimuli = path.join(work, 'stimuli');
  const lists = path.join(work, 'lists.csv');
  const study = path.join(work, 'study');
  run('build-stimuli', protocol, '--out', stimuli);
  run('design', protocol, '--subjects', String(subjects), '--out', lists);
  run('export-web', protocol, '--stimuli', stimuli, '--lists', lists, '--out', study);
  const config = JSON.parse(fs.readFileSync(path.join(study, 'study.json'), 'utf8'));
  return { stimuli, lists, study, config };
}

export function readCsv(file) {
  const lines = fs.readFileSync(file, 'utf8').trim().split('\n');
  const parse = (line) => {
    const out = []; let field = ''; let quoted = false;
    for (let i = 0; i < line.length; i++) {
      const c = line[i];
      if (quoted) { if (c === '"' && line[i + 1] === '"') { field += '"'; i++; } else if (c === '"') quoted = false; else field += c; }
      else if (c === '"') quoted = true; else if (c === ',') { out.push(field); field = ''; } else field += c;
    }
    out.push(field);
    return out;
  };
  const header = parse(lines[0]);
  return lines.slice(1).map((l) => Object.fromEntries(parse(l).map((v, i) => [header[i], v])));
}

const types = { '.html': 'text/html', '.js': 'text/javascript', '.css': 'text/css', '.json': 'application/json', '.mp4': 'video/mp4', '.wav': 'audio/wav' };

// A static server for the study folder on 127.0.0.1; `routes` maps a path to
// a handler (req, res, body) that answers it (POST bodies read first).
export async function serveStudy(study, routes = {}) {
  const server = http.createServer((req, res) => {
    const url = new URL(req.url, 'http://localhost');
    const route = routes[url.pathname];
    if (route) {
      let body = '';
      req.on('data', (chunk) => { body += chunk; });
      req.on('end', () => route(req, res, body, url));
      return;
    }
    const file = path.join(study, path.normalize(decodeURIComponent(url.pathname)).replace(/^(\.\.[/\\])+/, ''));
    if (!file.startsWith(study) || !fs.existsSync(file) || fs.statSync(file).isDirectory()) { res.writeHead(404); res.end(); return; }
    res.writeHead(200, { 'Content-Type': types[path.extname(file)] || 'application/octet-stream' });
    res.end(fs.readFileSync(file));
  });
  await new Promise((resolve) => server.listen(0, '127.0.0.1', resolve));
  return { server, base: `http://127.0.0.1:${server.address().port}`, close: () => server.close() };
}

// Debian's chromium, headless, closed network, a fresh profile; `extra` flags added.
export function launchChromium(puppeteer, chromium, profile, extra = []) {
  fs.rmSync(profile, { recursive: true, force: true });
  return puppeteer.launch({
    executablePath: chromium,
    headless: true,
    args: ['--headless', '--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
      '--disable-component-update', '--disable-sync', `--user-data-dir=${profile}`, ...extra],
  });
}

// The JSON Lines of a text (records sent, downloaded or appended).
export function jsonLines(text) {
  return text.split('\n').filter((l) => l.trim() !== '').map((l) => JSON.parse(l));
}

// A scripted participant on one page (puppeteer's element clicks and typing).
export function scriptedParticipant(page, typed) {
  const clickButton = async (text) => {
    const handle = await page.waitForFunction((t) => [...document.querySelectorAll('button')].find((b) => b.textContent.trim() === t && !b.disabled), {}, text);
    await handle.click();
  };
  const answer = async (position, text) => {
    await page.waitForFunction((p) => window.avsiStudy.currentPosition === p && document.querySelector('#avsi-answer'), {}, position);
    await page.type('#avsi-answer', text);
    await page.keyboard.press('Enter');
    typed[position] = text;
  };
  const screening = async (test, trials) => {
    await clickButton('Begin');
    for (let i = 1; i <= trials; i++) {
      await page.waitForFunction((n) => document.body.textContent.includes(`Sound check ${n} of`) && [...document.querySelectorAll('button')].some((b) => b.textContent === '1' && !b.disabled), {}, i);
      const correct = await page.evaluate((t, n) => window.avsiStudy.screeningAnswer(t, n), test, i);
      await clickButton(String(correct));
    }
  };
  return { clickButton, answer, screening };
}
