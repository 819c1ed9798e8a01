// Opens the viewer's web page in Debian's chromium (headless, software GL) and takes
// screenshots when told, for tests/viewer.rs.
//
//   node screenshot.mjs URL
//
// Prints "ready" once the page has a canvas (the Wasm viewer is up), then reads commands
// on stdin, one per line: "shot PATH" writes a screenshot and prints "shot PATH";
// "quit" (or the end of stdin) closes the browser. Every wait is bounded.
import { chromium } from 'playwright-core';
import { createInterface } from 'node:readline';

const [url] = process.argv.slice(2);
if (!url) {
  console.error('usage: node screenshot.mjs URL');
  process.exit(2);
}
const watchdog = setTimeout(() => {
  console.error('screenshot.mjs: gave up after 600 s');
  process.exit(3);
}, 600000);

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM ?? '/usr/bin/chromium',
  headless: true,
  args: [
    '--use-gl=angle', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--no-sandbox',
    '--disable-background-networking', '--disable-component-update', '--disable-sync',
    '--no-first-run', '--disable-quic',
  ],
});
try {
  const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
  page.on('pageerror', (e) => console.error(`page error: ${e.message}`));
  await page.goto(url, { waitUntil: 'load', timeout: 60000 });
  await page.waitForSelector('canvas', { timeout: 60000 });
  console.log('ready');
  for await (const line of createInterface({ input: process.stdin })) {
    const [cmd, ...rest] = line.trim().split(' ');
    if (cmd === 'shot') {
      const path = rest.join(' ');
      await page.screenshot({ path });
      console.log(`shot ${path}`);
    } else if (cmd === 'quit') {
      break;
    }
  }
} finally {
  clearTimeout(watchdog);
  await browser.close();
}
// stdin would keep the process alive.
process.exit(0);
