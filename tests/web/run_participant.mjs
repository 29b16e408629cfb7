// A tool, not a test: one scripted participant takes an exported study
// (`avsi export-web`) from start to end in headless Chromium (Chromium's
// default autoplay policy; the Start click and every key are real input
// events), typing each sentence's text from the corpus (or "answer N"), and
// the records are written as JSON Lines for `avsi import-web`. Used to
// measure the timing certificate of the demo's web export
// (docs/online-study.md):
//
//   node tests/web/run_participant.mjs --study out/demo/web --subject 1 \
//        --corpus protocols/corpus/sentences-en.csv --out out/web-run/results.jsonl [--chromium /usr/bin/chromium]
//
// The study is served from 127.0.0.1 only; its results_url, if any, is
// answered by this server too.
import fs from 'node:fs';
import path from 'node:path';
import { launchChromium, loadPuppeteer, parseArgs, serveStudy } from './harness.mjs';

const args = parseArgs(process.argv.slice(2));
if (!args.study || !args.out) { console.error('usage: run_participant.mjs --study DIR --out FILE [--subject N] [--corpus CSV] [--chromium PATH]'); process.exit(2); }
const study = path.resolve(args.study);
const subject = String(args.subject || 1);
const chromium = args.chromium || '/usr/bin/chromium';
const puppeteer = loadPuppeteer(chromium);
const config = JSON.parse(fs.readFileSync(path.join(study, 'study.json'), 'utf8'));
const plan = config.subjects[subject];
if (!plan) { console.error(`subject ${subject} is not in ${study}/study.json`); process.exit(2); }
// The corpus' text per sentence id (columns id and text).
const texts = {};
if (args.corpus) {
  const lines = fs.readFileSync(args.corpus, 'utf8').split('\n').filter((l) => l.trim());
  const header = lines[0].split(',');
  const id = header.indexOf('id');
  const text = header.indexOf('text');
  for (const line of lines.slice(1)) {
    const fields = line.match(/("([^"]|"")*"|[^,]*)(,|$)/g).map((f) => f.replace(/,$/, '').replace(/^"|"$/g, '').replace(/""/g, '"'));
    texts[fields[id]] = fields[text];
  }
}
const posted = [];
const { base, close } = await serveStudy(study, {
  [config.online.results_url || '/results']: (req, res, body) => { posted.push(body); res.writeHead(204); res.end(); },
});
const work = path.dirname(path.resolve(args.out));
fs.mkdirSync(work, { recursive: true });
const browser = await launchChromium(puppeteer, chromium, path.join(work, 'profile'));
const started = Date.now();
try {
  const page = await browser.newPage();
  page.on('pageerror', (e) => console.error(`page error: ${e}`));
  await page.goto(`${base}/index.html?subject=${subject}`);
  const state = () => page.evaluate(() => ({
    text: document.body.innerText,
    buttons: [...document.querySelectorAll('button')].filter((b) => !b.disabled).map((b) => { const r = b.getBoundingClientRect(); return { text: b.textContent.trim(), x: r.x + r.width / 2, y: r.y + r.height / 2 }; }),
    answer: !!document.querySelector('#avsi-answer'),
    position: window.avsiStudy ? window.avsiStudy.currentPosition : 0,
    answered: window.avsiStudy ? window.avsiStudy.answered.length : 0,
  }));
  let lastKey = '';
  let same = 0;
  for (;;) {
    const s = await state();
    const key = `${s.text}|${s.buttons.map((b) => b.text).join(',')}|${s.answer}|${s.position}`;
    if (key === lastKey) { same++; await new Promise((r) => setTimeout(r, 100)); if (same > 1200) throw new Error(`stuck on: ${s.text.slice(0, 200)}`); continue; }
    same = 0;
    const button = (t) => s.buttons.find((b) => b.text === t);
    let acted = true;
    if (button('Start')) await page.mouse.click(button('Start').x, button('Start').y);
    else if (button('The level is comfortable')) await page.keyboard.press('Enter');
    else if (/Sound check (\d+) of/.test(s.text) && button('1')) {
      const n = Number(/Sound check (\d+) of/.exec(s.text)[1]);
      const answer = await page.evaluate((t, i) => window.avsiStudy.screeningAnswer(t, i), /softest/.test(s.text) ? 'antiphase' : 'huggins', n);
      await page.keyboard.press(String(answer));
    } else if (s.answer) {
      const t = plan.find((p) => p.position === s.position);
      await page.keyboard.type(texts[t.sentence] || `answer ${s.position}`);
      await page.keyboard.press('Enter');
    } else if (button('Finish')) {
      break;  // not clicked: it would go to the protocol's completion URL (off this machine)
    } else if (button('Begin') || button('Continue')) await page.keyboard.press(' ');
    else acted = false;
    if (acted) lastKey = key;
    else await new Promise((r) => setTimeout(r, 100));
  }
  const text = await page.evaluate(() => window.avsiStudy.resultsText());
  fs.writeFileSync(args.out, text);
  console.log(`subject ${subject}: ${plan.length} trials in ${((Date.now() - started) / 1000).toFixed(0)} s; ${text.trim().split('\n').length} records written to ${args.out}` +
    (posted.length ? ` (${posted.length} POSTs answered)` : ''));
} finally {
  await browser.close();
  close();
}
