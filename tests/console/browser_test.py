#!/usr/bin/python3
"""Browser test of the operator's console (issue 17): headless Chromium from Debian drives the page served by
`rangebayes replay recordings/synth_planes_320x240 --ui 127.0.0.1:0`.

Checks: the page loads with no console errors, receives depth frames and at least one mesh, the 3D canvas is
not blank (its pixels are read), start/stop recording through the page writes a recording that `rangebayes
replay` reads, and a wrong token is refused where the operator sees it (1280x800). Then: a settings field the
operator changed is not overwritten by status updates and "set" sends it, an empty budget is not sent, the
phone layout (390x844) keeps every panel visible without sideways scrolling, switching back to SGBM takes the σ
map away, "capture now" on the live path gives a capture, and when the process stops the page says it is
disconnected and retrying (the live values marked stale), then, with a restarted process on the same port, that
it restarted and needs the new token (its old captures gone). Keeps a screenshot in OUT/console_screenshot.png.

Chromium is driven through the DevTools protocol over --remote-debugging-pipe (fds 3 and 4, messages ended
by NUL), so the driver needs only the Python standard library. Every process is started here and stopped in
the finally block (and on SIGTERM).

usage: browser_test.py RANGEBAYES_BINARY OUT_DIR [--chromium /usr/bin/chromium] [--bench SECONDS [--repeats N]]
"""
import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

# Waits on rangebayes (not on Chromium) are multiplied by this: the sanitizer builds run it several times slower.
TIMEOUT_FACTOR = float(os.environ.get("RANGEBAYES_TEST_TIMEOUT_FACTOR", "1"))
REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
RECORDING = os.path.join(REPO, "recordings", "synth_planes_320x240")


class Cdp:
    """A DevTools protocol client over Chromium's --remote-debugging-pipe."""

    def __init__(self, chromium, user_data_dir, log_path):
        to_child_r, self._to_child_w = os.pipe()
        self._from_child_r, from_child_w = os.pipe()
        # The child's ends move above 10, out of the way of the 3 and 4 that dup2 puts them on.
        a, b = fcntl_dup_high(to_child_r), fcntl_dup_high(from_child_w)

        def child_fds():
            os.dup2(a, 3)
            os.dup2(b, 4)

        args = [chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                "--disable-background-networking", "--disable-component-update", "--disable-sync",
                "--disable-default-apps", "--disable-extensions", "--mute-audio", "--no-default-browser-check",
                "--use-angle=swiftshader", "--enable-unsafe-swiftshader", "--window-size=1440,1000",
                "--remote-debugging-pipe", f"--user-data-dir={user_data_dir}", "about:blank"]
        self._log = open(log_path, "wb")
        self.proc = subprocess.Popen(args, stdin=subprocess.DEVNULL, stdout=self._log, stderr=subprocess.STDOUT,
                                     close_fds=False, preexec_fn=child_fds)
        os.close(a)
        os.close(b)
        self._next_id = 0
        self._replies = {}
        self.events = []
        self._cv = threading.Condition()
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()
        self.session = None

    def _read(self):
        buf = b""
        while True:
            chunk = os.read(self._from_child_r, 1 << 16)
            if not chunk:
                with self._cv:
                    self._cv.notify_all()
                return
            buf += chunk
            while b"\0" in buf:
                raw, buf = buf.split(b"\0", 1)
                msg = json.loads(raw)
                with self._cv:
                    if "id" in msg:
                        self._replies[msg["id"]] = msg
                    else:
                        self.events.append(msg)
                    self._cv.notify_all()

    def call(self, method, params=None, session=True, timeout=30):
        with self._cv:
            self._next_id += 1
            mid = self._next_id
        msg = {"id": mid, "method": method, "params": params or {}}
        if session and self.session:
            msg["sessionId"] = self.session
        os.write(self._to_child_w, json.dumps(msg).encode() + b"\0")
        deadline = time.time() + timeout
        with self._cv:
            while mid not in self._replies:
                left = deadline - time.time()
                if left <= 0 or self.proc.poll() is not None:
                    raise RuntimeError(f"no DevTools reply to {method}")
                self._cv.wait(left)
            reply = self._replies.pop(mid)
        if "error" in reply:
            raise RuntimeError(f"{method}: {reply['error']}")
        return reply.get("result", {})

    def evaluate(self, expression, timeout=30):
        r = self.call("Runtime.evaluate", {"expression": expression, "awaitPromise": True, "returnByValue": True},
                      timeout=timeout)
        if "exceptionDetails" in r:
            raise RuntimeError(f"page exception in {expression!r}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait_for(self, expression, timeout, what):
        timeout *= TIMEOUT_FACTOR
        deadline = time.time() + timeout
        while time.time() < deadline:
            if self.evaluate(expression):
                return
            time.sleep(0.25)
        seen = self.evaluate("JSON.stringify({status_messages: rbConsole.statusMessages, meshes: rbConsole.meshes, "
                             "feedback: document.getElementById('feedback').textContent, "
                             "recording: rbConsole.lastStatus && rbConsole.lastStatus.recording})")
        raise AssertionError(f"timed out after {timeout} s waiting for {what} ({expression}); page: {seen}")

    def console_errors(self):
        with self._cv:
            events = list(self.events)
        errors = []
        for e in events:
            m, p = e.get("method"), e.get("params", {})
            if m == "Runtime.exceptionThrown":
                errors.append("exception: " + json.dumps(p.get("exceptionDetails", {}))[:400])
            elif m == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
                errors.append("console.error: " + json.dumps(p.get("args", []))[:400])
            elif m == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
                entry = p["entry"]
                errors.append(f"log ({entry.get('source')}): {entry.get('text')} {entry.get('url', '')}")
        return errors

    def close(self):
        try:
            if self.proc.poll() is None:
                try:
                    self.call("Browser.close", session=False, timeout=5)
                except Exception:
                    pass
                try:
                    self.proc.wait(timeout=5)
                except subprocess.TimeoutExpired:
                    self.proc.kill()
                    self.proc.wait()
        finally:
            self._log.close()


def fcntl_dup_high(fd):
    import fcntl
    high = fcntl.fcntl(fd, fcntl.F_DUPFD, 10)
    os.close(fd)
    return high


def start_replay(binary, out, extra, ui="127.0.0.1:0", name="run"):
    log_path = os.path.join(out, name + ".log")
    log = open(log_path, "wb")
    args = [binary, "replay", RECORDING, "--out", os.path.join(out, name), "--speed", "recorded",
            "--repeat", "100000", "--ui", ui] + extra
    proc = subprocess.Popen(args, cwd=REPO, stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT)
    deadline = time.time() + 60 * TIMEOUT_FACTOR
    pattern = re.compile(r"console at (http://\S+/) \(control token ([0-9a-f]+)")
    while time.time() < deadline:
        with open(log_path, "r", errors="replace") as f:
            m = pattern.search(f.read())
        if m:
            return proc, log, m.group(1), m.group(2)
        if proc.poll() is not None:
            break
        time.sleep(0.1)
    raise AssertionError("rangebayes replay --ui did not print its console address; see " + log_path)


def stop_process(proc, sig=signal.SIGINT, timeout=20):
    if proc is None or proc.poll() is not None:
        return
    proc.send_signal(sig)
    try:
        proc.wait(timeout=timeout * TIMEOUT_FACTOR)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()


CANVAS_NON_BLANK = """(() => {
  const c = window.rbConsole.canvas;
  if (!c) return -1;
  window.rbConsole.drawNow();
  const t = document.createElement('canvas');
  t.width = c.width; t.height = c.height;
  const g = t.getContext('2d');
  g.drawImage(c, 0, 0);
  const d = g.getImageData(0, 0, t.width, t.height).data;
  let lit = 0;
  for (let i = 0; i < d.length; i += 4) {
    if (Math.abs(d[i] - 0x14) + Math.abs(d[i + 1] - 0x17) + Math.abs(d[i + 2] - 0x1b) > 40) lit++;
  }
  return lit / (d.length / 4);
})()"""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("binary")
    ap.add_argument("out")
    ap.add_argument("--chromium", default="/usr/bin/chromium")
    ap.add_argument("--bench", type=float, default=0.0,
                    help="benchmark mode: seconds per phase; phases without and with the page alternate "
                         "(results/s, CPU of the pipeline, the console's threads and Chromium, capture-to-page "
                         "mesh latency)")
    ap.add_argument("--repeats", type=int, default=3,
                    help="benchmark mode: pairs of phases without and with the page (A B A B ...)")
    ap.add_argument("--page-args", default="",
                    help="benchmark mode: more of the page's hash parameters, e.g. images=30&meshes=30")
    ap.add_argument("replay_args", nargs="*", help="extra replay arguments (after --)")
    a = ap.parse_args()
    if not os.path.exists(a.chromium):
        print(f"browser_test: {a.chromium} not found (scripts/setup.sh installs chromium)", file=sys.stderr)
        return 1
    out = os.path.abspath(a.out)
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    replay = log = cdp = replay2 = log2 = None
    user_data = tempfile.mkdtemp(prefix="rb-chromium-")
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(1))
    try:
        extra = a.replay_args or ["--live-path"]
        replay, log, url, token = start_replay(a.binary, out, extra)
        print(f"browser_test: console at {url}")
        cdp = Cdp(a.chromium, user_data, os.path.join(out, "chromium.log"))
        target = cdp.call("Target.createTarget", {"url": "about:blank"}, session=False)["targetId"]
        cdp.session = cdp.call("Target.attachToTarget", {"targetId": target, "flatten": True},
                               session=False)["sessionId"]
        for domain in ("Runtime", "Log", "Page"):
            cdp.call(domain + ".enable")
        cdp.call("Emulation.setDeviceMetricsOverride",
                 {"width": 1440, "height": 1000, "deviceScaleFactor": 1, "mobile": False})
        cdp.call("Page.navigate", {"url": f"{url}#token={token}"})
        cdp.wait_for("typeof window.rbConsole === 'object' && window.rbConsole.statusMessages > 0", 30,
                     "the page and its first status message")
        if a.bench > 0:
            return bench(cdp, replay, url, token, a.bench, a.repeats, a.page_args)
        cdp.wait_for("rbConsole.images.depth >= 2 && rbConsole.images.left >= 2 && rbConsole.meshes >= 1", 90,
                     "depth frames and a mesh")
        assert cdp.evaluate("rbConsole.webgl") is True, "the page found no WebGL"
        # The mesh is drawn on the next animation frames: give the renderer a moment.
        deadline = time.time() + 20
        lit = 0.0
        while time.time() < deadline:
            lit = cdp.evaluate(CANVAS_NON_BLANK)
            if lit > 0.01:
                break
            time.sleep(0.25)
        assert lit > 0.01, f"the 3D canvas is blank ({lit:.4f} of its pixels differ from the background)"
        print(f"browser_test: {cdp.evaluate('rbConsole.images.depth')} depth frames, "
              f"{cdp.evaluate('rbConsole.meshes')} meshes, {100 * lit:.1f}% of the 3D canvas lit")

        # Recording through the page's own buttons.
        cdp.evaluate("document.getElementById('rec-name').value = 'browser_rec'; "
                     "document.getElementById('rec-start').click(); true")
        cdp.wait_for("document.getElementById('feedback').textContent.startsWith('record_start: ok')", 10,
                     "the recording to start")
        cdp.wait_for("rbConsole.lastStatus.recording.active && rbConsole.lastStatus.recording.frames_written >= 3",
                     60, "three recorded frames")
        cdp.evaluate("document.getElementById('rec-stop').click(); true")
        cdp.wait_for("document.getElementById('feedback').textContent.startsWith('record_stop: ok')", 20,
                     "the recording to stop")
        rec = os.path.join(out, "run", "recordings", "browser_rec")
        check = subprocess.run([a.binary, "replay", rec, "--out", os.path.join(out, "reread"), "--no-smooth",
                                "--no-decimate", "--no-previews", "--count", "3", "-q"], cwd=REPO, capture_output=True, text=True,
                               timeout=120 * TIMEOUT_FACTOR)
        assert check.returncode == 0, f"the page's recording does not replay: {check.stdout}{check.stderr}"
        with open(os.path.join(rec, "frames.csv")) as f:
            frames = len(f.readlines()) - 1
        assert frames >= 3, f"the page's recording holds {frames} frames"
        print(f"browser_test: recording from the page: {frames} frames, replayed")

        cdp.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")
        shot = cdp.call("Page.captureScreenshot", {"format": "png"})
        import base64
        with open(os.path.join(out, "console_screenshot.png"), "wb") as f:
            f.write(base64.b64decode(shot["data"]))

        # Text from the server is shown as text: an error line or a recording folder may hold any character (a
        # file name of a recording), and markup in them was inserted as HTML.
        shown = cdp.evaluate(
            "(() => { const s = JSON.parse(JSON.stringify(rbConsole.lastStatus));"
            " const markup = '<img src=x onerror=\"window.rbInjected = 1\">';"
            " s.errors = [markup]; s.recording.active = true; s.recording.folder = markup; s.recording.error = markup;"
            " rbConsole.showStatus(s);"
            " return { img: document.querySelectorAll('#errors img, #recording img').length,"
            " text: document.getElementById('errors').textContent + '|' + document.getElementById('recording')"
            ".textContent }; })()")
        assert shown["img"] == 0 and shown["text"].count("<img src=x") == 3, f"server text shown as markup: {shown}"
        time.sleep(0.3)
        assert cdp.evaluate("window.rbInjected === undefined"), "markup from the server ran on the page"

        errors = cdp.console_errors()
        assert not errors, "console errors on the page:\n  " + "\n  ".join(errors)

        # A wrong token is refused and changes nothing, and the refusal is on screen at 1280x800 (it was below
        # the fold, in the side panel).
        set_viewport(cdp, 1280, 800)
        cdp.evaluate("document.getElementById('token').value = 'not-the-token'; "
                     "document.getElementById('pause').click(); true")
        cdp.wait_for("document.getElementById('feedback').textContent.includes('refused (403)')", 10,
                     "the refusal of a wrong token")
        box = cdp.evaluate("(() => { const r = document.getElementById('feedback').getBoundingClientRect();"
                           " return [r.top, r.bottom, r.height, window.innerHeight]; })()")
        assert box[2] > 0 and box[0] >= 0 and box[1] <= box[3], f"the refusal is not on screen at 1280x800: {box}"
        time.sleep(1.0)
        assert cdp.evaluate("rbConsole.lastStatus.settings.paused") is False, "a wrong token paused the run"
        # The one error the browser logs now is the 403 of that request; nothing else may appear.
        late = [e for e in cdp.console_errors()[len(errors):] if "403" not in e]
        assert not late, "console errors after the wrong token:\n  " + "\n  ".join(late)
        print("browser_test: wrong token refused, on screen at 1280x800; screenshot in " +
              os.path.join(out, "console_screenshot.png"))
        cdp.evaluate(f"document.getElementById('token').value = '{token}'; true")
        set_viewport(cdp, 1440, 1000)

        check_settings_fields(cdp)
        check_phone_layout(cdp)
        check_sigma_after_sgbm(cdp)

        # "capture now" on the live path: the full-quality frame was dropped by the queue after capture.
        cdp.evaluate("document.getElementById('capture').click(); true")
        cdp.wait_for("document.getElementById('feedback').textContent.startsWith('capture_now: ok')", 10,
                     "capture_now to be accepted")
        cdp.wait_for("document.querySelectorAll('#captures li').length >= 1", 180, "the capture to arrive")
        assert cdp.evaluate("rbConsole.lastStatus.capture_error") == "", "the capture reported an error"
        print("browser_test: capture now on the live path arrived")

        # The process vanishes (killed: a crash, a pulled cable): the page says so, marks what it shows as stale and
        # retries. Not SIGINT: a run that ends in order sends a last status with finished set, which disables the
        # controls, so whether a control could still be clicked would race that message against the closing socket.
        port = re.search(r":(\d+)/$", url).group(1)
        stop_process(replay, signal.SIGKILL)
        cdp.wait_for("document.body.classList.contains('disconnected')"
                     " && document.getElementById('run').textContent !== 'running'"
                     " && document.getElementById('fps').textContent === '-'"
                     " && /retrying/.test(document.getElementById('banner').textContent)", 20,
                     "the page to show that it lost the connection")
        cdp.evaluate("document.getElementById('pause').click(); true")
        cdp.wait_for("document.getElementById('feedback').textContent.includes('not sent: no connection')", 10,
                     "a control without connection to be named a network failure")
        print("browser_test: disconnection shown: " + cdp.evaluate("document.getElementById('banner').textContent"))

        # A new process on the same port has a new token and no captures: the page says that it restarted.
        replay2, log2, _, token2 = start_replay(a.binary, out, extra, ui=f"127.0.0.1:{port}", name="run2")
        assert token2 != token
        cdp.wait_for("!document.body.classList.contains('disconnected')"
                     " && /restarted/.test(document.getElementById('banner').textContent)", 60,
                     "the page to reconnect and tell the restart")
        assert cdp.evaluate("document.querySelectorAll('#captures li').length") == 0, "captures of the old run kept"
        cdp.evaluate("document.getElementById('pause').click(); true")
        cdp.wait_for("/refused \\(403\\).*restarted/.test(document.getElementById('feedback').textContent)", 10,
                     "the old token's refusal to name the restart")
        print("browser_test: restart told: " + cdp.evaluate("document.getElementById('banner').textContent"))
        print("browser_test: passed")
        return 0
    finally:
        for cleanup in (lambda: cdp and cdp.close(), lambda: stop_process(replay), lambda: log and log.close(),
                        lambda: stop_process(replay2), lambda: log2 and log2.close(),
                        lambda: shutil.rmtree(user_data, ignore_errors=True)):
            try:
                cleanup()
            except Exception as e:  # every process is stopped even when one cleanup fails
                print(f"browser_test: cleanup: {e}", file=sys.stderr)


def set_viewport(cdp, width, height, mobile=False):
    cdp.call("Emulation.setDeviceMetricsOverride",
             {"width": width, "height": height, "deviceScaleFactor": 1, "mobile": mobile})
    cdp.evaluate("new Promise(r => requestAnimationFrame(() => requestAnimationFrame(r)))")


def statuses_after(cdp, n):
    """An expression true once n more status messages have come than now."""
    return f"rbConsole.statusMessages >= {cdp.evaluate('rbConsole.statusMessages') + n}"


def check_settings_fields(cdp):
    """A field the operator changed keeps its value through status updates until it is sent; an empty budget is
    not sent."""
    cdp.evaluate("(() => { const b = document.getElementById('budget'); b.focus(); b.value = '30';"
                 " b.dispatchEvent(new Event('input', { bubbles: true })); b.blur(); return true; })()")
    cdp.wait_for(statuses_after(cdp, 3), 10, "three status messages")
    shown = cdp.evaluate("document.getElementById('budget').value")
    assert shown == "30", f"a status update overwrote the budget the operator typed (shows {shown!r})"
    cdp.evaluate("document.getElementById('budget-set').click(); true")
    cdp.wait_for("rbConsole.lastStatus.settings.smooth_budget_ms === 30", 10, "the budget to be set to 30")
    cdp.wait_for(statuses_after(cdp, 2), 10, "two status messages")
    assert cdp.evaluate("document.getElementById('budget').classList.contains('dirty')") is False
    cdp.evaluate("document.getElementById('budget').value = ''; document.getElementById('budget')"
                 ".dispatchEvent(new Event('input')); document.getElementById('budget-set').click(); true")
    cdp.wait_for("document.getElementById('feedback').textContent.includes('not sent')", 10,
                 "an empty budget to be refused in the page")
    cdp.wait_for(statuses_after(cdp, 2), 10, "two status messages")
    assert cdp.evaluate("rbConsole.lastStatus.settings.smooth_budget_ms") == 30, "an empty budget was sent"
    cdp.evaluate("document.getElementById('budget-none').click(); true")
    cdp.wait_for("rbConsole.lastStatus.settings.smooth_budget_ms === 0", 10, "no budget")
    cdp.evaluate("document.getElementById('budget').value = '80'; document.getElementById('budget')"
                 ".dispatchEvent(new Event('input')); document.getElementById('budget-set').click(); true")
    cdp.wait_for("rbConsole.lastStatus.settings.smooth_budget_ms === 80", 10, "the live path's budget again")
    print("browser_test: a changed field is kept until sent; an empty budget is not sent")


def check_phone_layout(cdp):
    """At 390x844 every panel keeps a width and the page does not scroll sideways."""
    set_viewport(cdp, 390, 844, mobile=True)
    sizes = cdp.evaluate("(() => { const w = (id) => document.getElementById(id).getBoundingClientRect().width;"
                         " return { left: w('img-left'), depth: w('img-depth'), sigma: w('img-sigma'),"
                         " mesh: w('view3d'), side: w('side'), scroll: document.documentElement.scrollWidth,"
                         " inner: window.innerWidth }; })()")
    set_viewport(cdp, 1440, 1000)
    for k in ("left", "depth", "sigma", "mesh", "side"):
        assert sizes[k] > 200, f"at 390x844 the {k} panel is {sizes[k]} px wide: {sizes}"
    assert sizes["scroll"] <= sizes["inner"], f"at 390x844 the page scrolls sideways: {sizes}"
    print(f"browser_test: phone layout: {sizes}")


def check_sigma_after_sgbm(cdp):
    """Space-time gives σ maps; SGBM again takes the last one away and says why."""
    def matcher(name):
        cdp.evaluate(f"(() => {{ const m = document.getElementById('matcher'); m.value = '{name}';"
                     " m.dispatchEvent(new Event('change')); document.getElementById('matcher-set').click();"
                     " return true; })()")
        cdp.wait_for(f"rbConsole.lastStatus.settings.matcher === '{name}'", 10, f"the matcher {name}")
    sigma = cdp.evaluate("rbConsole.images.sigma")
    matcher("spacetime")
    cdp.wait_for(f"rbConsole.images.sigma > {sigma} && document.getElementById('img-sigma').getAttribute('src')",
                 90, "a σ map from space-time")
    assert cdp.evaluate("document.getElementById('sigma-note').textContent") == ""
    matcher("sgbm")
    cdp.wait_for("!document.getElementById('img-sigma').getAttribute('src')"
                 " && document.getElementById('sigma-note').textContent.includes('none from this matcher')", 60,
                 "the σ map to go with SGBM")
    print("browser_test: σ map shown with space-time, taken away with SGBM")


def proc_cpu_s(pid):
    """User + system CPU seconds of one process (all its threads), 0 when it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, IndexError, ValueError):
        return 0.0


def thread_cpu_s(pid):
    """CPU seconds of each thread of `pid`, summed by thread name (the console names its two threads)."""
    out = {}
    try:
        tids = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return out
    for tid in tids:
        try:
            with open(f"/proc/{pid}/task/{tid}/comm") as f:
                name = f.read().strip()
            with open(f"/proc/{pid}/task/{tid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            out[name] = out.get(name, 0.0) + (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
        except (OSError, IndexError, ValueError):
            pass
    return out


def descendants(pid):
    """`pid` and every process below it."""
    children = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    ppid = int(f.read().rsplit(")", 1)[1].split()[1])
                children.setdefault(ppid, []).append(int(d))
            except (OSError, IndexError, ValueError):
                pass
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        out.append(p)
        todo.extend(children.get(p, []))
    return out


def cpu_snapshot(replay_pid, chromium_pid):
    # Chromium's processes come and go with navigation: sum the living ones and the ones reaped (cutime).
    chrome = 0.0
    for p in descendants(chromium_pid):
        chrome += proc_cpu_s(p)
        if p == chromium_pid:
            try:
                with open(f"/proc/{p}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
                chrome += (int(fields[13]) + int(fields[14])) / os.sysconf("SC_CLK_TCK")
            except (OSError, IndexError, ValueError):
                pass
    by_type = {}
    for p in descendants(chromium_pid):
        try:
            with open(f"/proc/{p}/cmdline", "rb") as f:
                m = re.search(rb"--type=([a-z-]+)", f.read())
            kind = m.group(1).decode() if m else "browser"
        except OSError:
            continue
        by_type[kind] = by_type.get(kind, 0.0) + proc_cpu_s(p)
    threads = thread_cpu_s(replay_pid)
    console = sum(v for k, v in threads.items() if k.startswith("rb-console"))
    return {"t": time.time(), "rangebayes": proc_cpu_s(replay_pid), "console_threads": console, "chromium": chrome,
            "chromium_by_type": by_type}


def http_status(url):
    import urllib.request
    with urllib.request.urlopen(url + "api/status", timeout=10) as r:
        return json.loads(r.read())


def percentile(values, q):
    if not values:
        return None
    v = sorted(values)
    return v[min(len(v) - 1, int(round(q * (len(v) - 1))))]


def rounded(x):
    return None if x is None else round(x, 1)


def bench(cdp, replay, url, token, seconds, repeats, page_args):
    """Interleaved phases in one replay process at the same load: A without the page (the tab on about:blank,
    no WebSocket client), B with the page open; A B A B ... Prints one JSON line per phase and a summary."""
    settle_s = 3.0
    phases = []
    load_start = os.getloadavg()
    for i in range(2 * repeats):
        with_page = i % 2 == 1
        if with_page:
            cdp.call("Page.navigate", {"url": f"{url}#token={token}" + (f"&{page_args}" if page_args else "")})
            cdp.wait_for("typeof window.rbConsole === 'object' && rbConsole.meshes >= 1", 60, "a first mesh")
        else:
            cdp.call("Page.navigate", {"url": "about:blank"})
        time.sleep(settle_s)
        if with_page:
            cdp.evaluate("rbConsole.latencies.length = 0; (rbConsole.toPage || []).length = 0; "
                         "rbConsole.meshesAtStart = rbConsole.meshes; true")
        s0, c0 = http_status(url), cpu_snapshot(replay.pid, cdp.proc.pid)
        time.sleep(seconds)
        s1, c1 = http_status(url), cpu_snapshot(replay.pid, cdp.proc.pid)
        wall = c1["t"] - c0["t"]
        phase = {"phase": "page" if with_page else "no page", "results_per_s": (s1["results"] - s0["results"]) / wall,
                 "dropped_per_s": (s1["dropped"] - s0["dropped"]) / wall,
                 "cpu_rangebayes": (c1["rangebayes"] - c0["rangebayes"]) / wall,
                 "cpu_console_threads": (c1["console_threads"] - c0["console_threads"]) / wall,
                 "cpu_chromium": (c1["chromium"] - c0["chromium"]) / wall,
                 "cpu_chromium_by_process": {k: round((v - c0["chromium_by_type"].get(k, 0.0)) / wall, 3)
                                             for k, v in c1["chromium_by_type"].items()},
                 "load1": os.getloadavg()[0]}
        if with_page:
            page = cdp.evaluate("({l: rbConsole.latencies.slice(), t: (rbConsole.toPage || []).slice(), "
                                "m: rbConsole.meshes - rbConsole.meshesAtStart})")
            lat = page["l"]
            phase.update({"meshes_per_s_on_page": page["m"] / wall, "latency_samples": len(lat),
                          "latency_ms_median": rounded(percentile(lat, 0.5)), "latency_ms_p95": rounded(percentile(lat, 0.95)),
                          "sent_to_drawn_ms_median": percentile(page["t"], 0.5), "latencies": lat,
                          "to_page": page["t"]})
            phase["console"] = s1["console"]
        phases.append(phase)
        print("bench: " + json.dumps({k: (round(v, 3) if isinstance(v, float) else v)
                                      for k, v in phase.items() if k not in ("latencies", "to_page")}), flush=True)
    a = [p["results_per_s"] for p in phases if p["phase"] == "no page"]
    b = [p["results_per_s"] for p in phases if p["phase"] == "page"]
    lat = [x for p in phases if p["phase"] == "page" for x in p["latencies"]]
    to_page = [x for p in phases if p["phase"] == "page" for x in p["to_page"]]
    mean = lambda v: sum(v) / len(v)
    summary = {"seconds_per_phase": seconds, "repeats": repeats, "page_args": page_args,
               "results_per_s_no_page": round(mean(a), 2), "results_per_s_page": round(mean(b), 2),
               "ratio": round(mean(b) / mean(a), 3),
               "latency_ms_median": rounded(percentile(lat, 0.5)), "latency_ms_p95": rounded(percentile(lat, 0.95)),
               "latency_samples": len(lat), "sent_to_drawn_ms_median": percentile(to_page, 0.5),
               "sent_to_drawn_ms_p95": percentile(to_page, 0.95),
               "cpu_chromium_page": round(mean([p["cpu_chromium"] for p in phases if p["phase"] == "page"]), 3),
               "cpu_console_threads_page": round(mean([p["cpu_console_threads"] for p in phases
                                                      if p["phase"] == "page"]), 3),
               "cpu_console_threads_no_page": round(mean([p["cpu_console_threads"] for p in phases
                                                         if p["phase"] == "no page"]), 3),
               "load_start": [round(x, 2) for x in load_start], "load_end": [round(x, 2) for x in os.getloadavg()]}
    print("bench summary: " + json.dumps(summary), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
