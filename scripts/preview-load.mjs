// Load time of a preview page in headless Chromium, by the DevTools
// protocol: the wall time from Page.navigate until the page reports itself
// drawn (window.idexpState.ready, set after its first frame is rendered).
// Usage: node --experimental-websocket scripts/preview-load.mjs PAGE.html [REPEATS]
// (Node ≥ 20.10 for its WebSocket; run by scripts/preview-bench.sh).
import { spawn } from 'node:child_process';
import { mkdtempSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { join, resolve } from 'node:path';

const [page, repeats = '3'] = process.argv.slice(2);
const url = 'file://' + resolve(page);
const port = 9300 + (process.pid % 500);
const profile = mkdtempSync(join(tmpdir(), 'idexp-preview-'));
const chrome = spawn('chromium', ['--headless', '--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
  '--window-size=1280,800', `--remote-debugging-port=${port}`, `--user-data-dir=${profile}`, 'about:blank'], { stdio: 'ignore' });
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
try {
  let target;
  for (let i = 0; i < 200 && !target; i++) {
    try {
      const list = await (await fetch(`http://127.0.0.1:${port}/json/list`)).json();
      target = list.find((t) => t.type === 'page');
    } catch { await sleep(50); }
  }
  if (!target) throw new Error('chromium did not start');
  const ws = new WebSocket(target.webSocketDebuggerUrl);
  await new Promise((r, e) => { ws.onopen = r; ws.onerror = e; });
  let id = 0;
  const pending = new Map();
  ws.onmessage = (m) => { const d = JSON.parse(m.data); if (pending.has(d.id)) { pending.get(d.id)(d); pending.delete(d.id); } };
  const send = (method, params = {}) => new Promise((r) => { pending.set(++id, r); ws.send(JSON.stringify({ id, method, params })); });
  await send('Page.enable');
  for (let k = 0; k < Number(repeats); k++) {
    await send('Page.navigate', { url: 'about:blank' });
    await sleep(200);
    const t0 = performance.now();
    await send('Page.navigate', { url });
    let state = null;
    while (performance.now() - t0 < 60000) {
      const r = await send('Runtime.evaluate', { expression: 'window.idexpState && window.idexpState.ready ? JSON.stringify({frames: idexpState.frames, error: idexpState.error || null, timing: idexpState.timing || null}) : null', returnByValue: true });
      if (r.result && r.result.result && r.result.result.value) { state = JSON.parse(r.result.result.value); break; }
      await sleep(10);
    }
    const ms = performance.now() - t0;
    if (!state) throw new Error('the page did not get ready within 60 s');
    const tm = state.timing ? ' — in the page (ms since navigation): ' + Object.entries(state.timing).map(([k, v]) => `${k} ${v}`).join(', ') : '';
    console.log(`load ${(ms / 1000).toFixed(2)} s (navigate to first drawn frame), ${state.frames} frames${state.error ? ', error ' + state.error : ''}${tm}`);
  }
  ws.close();
} finally {
  chrome.kill();
  await sleep(300);
  rmSync(profile, { recursive: true, force: true });
}
