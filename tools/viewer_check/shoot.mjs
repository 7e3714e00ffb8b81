// Headless-chromium screenshot of www/index.html via playwright-core.
// usage: [WIDTH=960 HEIGHT=720] node shoot.mjs <page-url> <out.png> [settle-ms]
import { chromium } from 'playwright-core';
import fs from 'node:fs';
import os from 'node:os';
import path from 'node:path';

const [pageUrl, out, settle = '4000'] = process.argv.slice(2);
const userDataDir = fs.mkdtempSync(path.join(os.tmpdir(), 'chromium-'));
const context = await chromium.launchPersistentContext(userDataDir, {
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  headless: true,
  viewport: { width: Number(process.env.WIDTH || 960), height: Number(process.env.HEIGHT || 720) },
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run',
         '--disable-background-networking', '--disable-component-update', '--disable-sync',
         '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});
const page = context.pages()[0] || await context.newPage();
page.on('console', (m) => console.log(`[console.${m.type()}]`, m.text()));
page.on('pageerror', (e) => console.log('[pageerror]', e.message));
await page.goto(pageUrl);
await page.waitForFunction(() => window.__result && (window.__result.status === 'rendered' || window.__result.status === 'error'), null, { timeout: 180000 });
await page.waitForTimeout(Number(settle)); // let the background sort settle and a few more frames draw
const result = await page.evaluate(() => window.__result);
console.log('BROWSER', context.browser() ? context.browser().version() : '(persistent context)', await page.evaluate(() => navigator.userAgent));
console.log('RESULT', JSON.stringify(result));
await page.screenshot({ path: out });
await context.close();
fs.rmSync(userDataDir, { recursive: true, force: true });
if (result.status !== 'rendered') process.exit(1);
