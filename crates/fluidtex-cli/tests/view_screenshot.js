// Screenshots of `fluidtex view` pages in headless Chromium, taken only once
// the page says the frame is drawn (#status data-state="ready").
//
// Usage: node view_screenshot.js CHROMIUM WIDTH HEIGHT URL OUT.png [URL OUT.png ...]
// Prints one JSON line per shot: {url, out, status, stats_rows}.
//
// Why a driver and not `chromium --screenshot`: that flag shoots when its
// virtual time budget runs out, which with WebGL on SwiftShader sometimes
// comes before the glb and its texture are decoded (measured here: two of
// three `--dump-dom` tries of the same page still said "loading"). Here the DevTools protocol, over
// the pipe Chromium opens on fds 3 and 4 (--remote-debugging-pipe, no
// network port, no npm package), asks the page itself. One browser serves
// every shot, so SwiftShader starts once.

'use strict';
const { spawn } = require('child_process');
const fs = require('fs');

const [chrome, width, height, ...pairs] = process.argv.slice(2);
if (!chrome || pairs.length === 0 || pairs.length % 2 !== 0) {
  console.error('usage: node view_screenshot.js CHROMIUM WIDTH HEIGHT URL OUT.png [URL OUT.png ...]');
  process.exit(2);
}
const W = Number(width);
const H = Number(height);

const proc = spawn(chrome, [
  '--headless', '--no-sandbox', '--disable-dev-shm-usage', '--no-first-run',
  '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--hide-scrollbars',
  '--remote-debugging-pipe', `--window-size=${W},${H}`, 'about:blank',
], { stdio: ['ignore', 'ignore', 'ignore', 'pipe', 'pipe'] });
proc.on('exit', (code) => {
  if (!done) {
    console.error(`chromium exited early (${code})`);
    process.exit(1);
  }
});
let done = false;

let nextId = 0;
const pending = new Map();
let buffer = Buffer.alloc(0);
proc.stdio[4].on('data', (chunk) => {
  buffer = Buffer.concat([buffer, chunk]);
  let end;
  while ((end = buffer.indexOf(0)) >= 0) {
    const msg = JSON.parse(buffer.subarray(0, end).toString());
    buffer = buffer.subarray(end + 1);
    const p = msg.id !== undefined && pending.get(msg.id);
    if (p) {
      pending.delete(msg.id);
      if (msg.error) p.reject(new Error(`${p.method}: ${JSON.stringify(msg.error)}`));
      else p.resolve(msg.result);
    }
  }
});

function send(method, params = {}, sessionId = undefined) {
  const msg = { id: ++nextId, method, params };
  if (sessionId) msg.sessionId = sessionId;
  proc.stdio[3].write(`${JSON.stringify(msg)}\0`);
  return new Promise((resolve, reject) => pending.set(msg.id, { resolve, reject, method }));
}

const sleep = (ms) => new Promise((r) => setTimeout(r, ms));

async function main() {
  const { targetId } = await send('Target.createTarget', { url: 'about:blank' });
  const { sessionId } = await send('Target.attachToTarget', { targetId, flatten: true });
  await send('Emulation.setDeviceMetricsOverride',
    { width: W, height: H, deviceScaleFactor: 1, mobile: false }, sessionId);
  for (let k = 0; k < pairs.length; k += 2) {
    const [url, out] = [pairs[k], pairs[k + 1]];
    await send('Page.navigate', { url }, sessionId);
    const probe = `(() => {
      const s = document.getElementById('status');
      if (location.href !== ${JSON.stringify(url)} || !s) return 'none';
      return s.dataset.state + ': ' + s.textContent;
    })()`;
    let status = 'none';
    const deadline = Date.now() + 90000;
    while (Date.now() < deadline) {
      const r = await send('Runtime.evaluate', { expression: probe, returnByValue: true }, sessionId);
      status = r.result.value;
      if (status.startsWith('ready') || status.startsWith('error')) break;
      await sleep(100);
    }
    if (!status.startsWith('ready')) {
      throw new Error(`${url}: page not ready: ${status}`);
    }
    const rows = await send('Runtime.evaluate',
      { expression: "document.querySelectorAll('#stats tr').length", returnByValue: true }, sessionId);
    const { data } = await send('Page.captureScreenshot', { format: 'png' }, sessionId);
    fs.writeFileSync(out, Buffer.from(data, 'base64'));
    console.log(JSON.stringify({ url, out, status, stats_rows: rows.result.value }));
  }
}

main().then(() => {
  done = true;
  proc.kill();
  process.exit(0);
}, (err) => {
  done = true;
  console.error(`view_screenshot: ${err.message}`);
  proc.kill();
  process.exit(1);
});
