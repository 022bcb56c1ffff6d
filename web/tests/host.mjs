// The console on a server without tokens, opened by a name the server does not
// know (run by tests/tests/console.rs): the browser resolves `rebind.example` to
// the server's loopback address, as a DNS rebinding would, and the page says that
// its address is refused, naming the flag that would allow it, and does not ask
// for a token (none would help); the same server opened by its IP address, as
// localhost or by a name under .localhost lists the default scene. Checks in a real browser that its gRPC-web calls carry
// `Origin`, which the server's host check keys on, and that the page reads the
// refusal's mark.
// Usage: node host.mjs PORT OUT_DIR
import { launch, reportFailure, watch } from "./browser.mjs";

const [port, out] = process.argv.slice(2);
const NAME = "rebind.example";
const problems = [];
const T = 30_000;
let step = "start";

function check(cond, what) {
  if (!cond) throw new Error(`${step}: ${what}`);
}

const { context, close } = await launch([`--host-resolver-rules=MAP ${NAME} 127.0.0.1`]);
let status = 0;
try {
  step = "opened by a name not allowed";
  const rebound = await context.newPage();
  watch(rebound, "rebound", problems);
  await rebound.goto(`http://${NAME}:${port}/`);
  await rebound.waitForFunction(() => document.querySelector("#connection")?.dataset.state === "error", null, {
    timeout: T,
  });
  const said = await rebound.$eval("#notice", (e) => e.textContent);
  check(said.includes(`\`${NAME}\``), `the page says "${said}"`);
  check(said.includes(`--allowed-host ${NAME}`), `the page says "${said}"`);
  check(said.startsWith("this page's address is refused"), `the page says "${said}"`);
  check(!/enter a token|with this token/.test(said), `the page asks for a token: "${said}"`);
  check((await rebound.$$("#scenes tr[data-scene]")).length === 0, "scenes listed on a refused page");
  console.log(`ok a page opened as ${NAME} is refused: ${said}`);

  // The names allowed without a flag: the address, localhost and a name under
  // .localhost (which the browser resolves to loopback itself).
  for (const host of ["127.0.0.1", "localhost", "station-1.localhost"]) {
    step = `opened as ${host}`;
    const direct = await context.newPage();
    watch(direct, host, problems);
    await direct.goto(`http://${host}:${port}/`);
    await direct.waitForSelector('#scenes tr[data-scene="default"]', { timeout: T });
    await direct.close();
    console.log(`ok the same server opened as ${host} lists the default scene`);
  }

  check(problems.length === 0, problems.join("; "));
  console.log("host tests passed");
} catch (e) {
  await reportFailure(context, out, "host-failed", step, e, problems);
  status = 1;
} finally {
  await close();
}
process.exit(status);
