#!/usr/bin/python3
"""The dashboard in headless chromium (run by tests/dashboard/run.sh, inside
its network namespace). Checks, each printed as "ok: ..." or "FAILED: ...":

- the job appears on the farm page and its progress rises without a reload;
- a worker whose name is markup shows it as text (no element, no script);
- pausing from the job page stops new leases (checked through the CLI:
  `locus status`, `locus events`), resuming finishes the job;
- the frame page's image equals the fetched frame exactly (both decoded);
  a thumbnail is within 2/255 of a box-filtered downscale of the frame;
- a job submitted with --cost-map shows, while its frame of 24 bands
  renders (paused), the map of the bands done so far, equal to the one the
  API draws of them, and once written the frame's cost map, equal to the
  fetched map (max error 0); a job without shows none;
- the band map has one strip per band, the timed-out band is marked, and
  the predicted cost per row is drawn beside it;
- without a token the page asks for one and shows no job data, and the API
  answers 401 with none.
Screenshots of each page go to --out."""

import argparse
import base64
import io
import json
import os
import re
import subprocess
import sys
import time
import urllib.request

import numpy as np
from PIL import Image
from selenium import webdriver
from selenium.webdriver.chrome.service import Service
from selenium.webdriver.common.by import By

passed, failed = 0, 0


def check(ok, what, detail=""):
    global passed, failed
    if ok:
        passed += 1
        print("ok: " + what)
    else:
        failed += 1
        print("FAILED: " + what + (": " + str(detail) if detail else ""))
    sys.stdout.flush()
    return ok


def wait_for(predicate, seconds, step=0.1):
    end = time.time() + seconds
    while time.time() < end:
        try:
            value = predicate()
            if value:
                return value
        except Exception:  # the page may be between renders
            pass
        time.sleep(step)
    return None


def main():
    ap = argparse.ArgumentParser()
    for flag in ("url", "farm", "bin", "tokens", "job", "hung-pid", "out", "work", "scene"):
        ap.add_argument("--" + flag, required=True)
    a = ap.parse_args()
    ann = open(os.path.join(a.tokens, "ann.tok")).read().strip()
    job = a.job

    def locus(*args):
        return subprocess.run([os.path.join(a.bin, "locus"), *args, "--farm", a.farm,
                               "--token-file", os.path.join(a.tokens, "ann.tok")],
                              capture_output=True, text=True, timeout=60)

    def api(path):
        req = urllib.request.Request(a.url + "/api/v1/" + path,
                                     headers={"Authorization": "Bearer " + ann})
        with urllib.request.urlopen(req, timeout=10) as r:
            return json.loads(r.read())

    # A grant reads "lease L: band B of frame F to worker W (name), attempt A";
    # a lease's end ("lease L timed out: band hung: leased to worker ...")
    # also names a worker and is not a grant.
    grant = re.compile(r"\blease \S+: band \d+ of frame \d+ to worker ")

    def leases():
        return sum(1 for line in locus("events", job).stdout.splitlines() if grant.search(line))

    opts = webdriver.ChromeOptions()
    opts.binary_location = "/usr/bin/chromium"
    for flag in ("--headless=new", "--no-sandbox", "--disable-gpu", "--disable-dev-shm-usage",
                 "--disable-background-networking", "--disable-component-update",
                 "--disable-default-apps", "--disable-sync", "--disable-extensions",
                 "--disable-client-side-phishing-detection", "--disable-domain-reliability",
                 "--disable-breakpad", "--metrics-recording-only", "--no-first-run",
                 "--no-default-browser-check", "--safebrowsing-disable-auto-update",
                 "--disable-features=Translate,OptimizationHints,MediaRouter,"
                 "DialMediaRouteProvider,AutofillServerCommunication,CertificateTransparencyComponentUpdater",
                 "--window-size=1400,1100", "--force-color-profile=srgb", "--user-data-dir=" + os.path.join(a.work, "chromium")):
        opts.add_argument(flag)
    try:
        driver = webdriver.Chrome(service=Service("/usr/bin/chromedriver"), options=opts)
    except Exception as e:
        check(False, "chromium starts", e)
        return 1
    driver.set_page_load_timeout(30)
    shot = lambda name: driver.save_screenshot(os.path.join(a.out, name + ".png"))
    try:
        # ---- the farm page: the job, its progress rising without a reload
        driver.get(a.url + "/#token=" + ann)
        row = wait_for(lambda: driver.find_element(By.CSS_SELECTOR, f'#jobs tr[data-job="{job}"]'), 10)
        check(row is not None, "the job appears on the farm page")
        check("token" not in driver.current_url, "the token left the address bar", driver.current_url)
        driver.execute_script("window.notReloaded = 1;")
        progress = lambda: int(driver.find_element(
            By.CSS_SELECTOR, f'#jobs tr[data-job="{job}"] td.progress').text.split("/")[0])
        first = wait_for(progress, 10) or 0
        later = wait_for(lambda: progress() > first + 10 and progress(), 20)
        check(later and driver.execute_script("return window.notReloaded === 1;"),
              f"progress rises without a reload ({first} -> {later} bands)")
        name = wait_for(lambda: [td for td in driver.find_elements(By.CSS_SELECTOR, "#workers td.name")
                                 if "<img" in td.text], 10)
        check(name and not name[0].find_elements(By.TAG_NAME, "img")
              and not driver.execute_script("return window.xss === 1;"),
              "a worker named with markup shows it as text")
        shot("farm")

        # ---- the job page: pause from the page, checked through the CLI
        driver.get(a.url + "/#/job/" + job)
        button = wait_for(lambda: driver.find_element(By.ID, "pause"), 10)
        button.click()
        paused = wait_for(lambda: "paused" in locus("status", job).stdout, 10)
        check(paused, "pausing from the page pauses the job (locus status)")
        time.sleep(1.0)  # bands in flight end; no new lease is granted
        before = leases()
        time.sleep(3.0)
        after = leases()
        check(after == before, f"no new lease for 3 s while paused ({before} -> {after})")
        shot("job-paused")
        # The hung worker's band was taken back by the band timeout: it
        # can go now (it would take more bands and hang again).
        hung = wait_for(lambda: [e for e in api(f"jobs/{job}/events?after=0")["events"]
                                 if "timed out" in e["text"]], 20)
        check(hung, "the hung band was taken back (events)")
        subprocess.run(["kill", "-9", a.hung_pid])
        driver.find_element(By.ID, "resume").click()
        done = wait_for(lambda: "succeeded" in locus("status", job).stdout, 90, 0.5)
        check(done, "resuming from the page finishes the job")
        thumbs = wait_for(lambda: len(driver.find_elements(By.CSS_SELECTOR, "#thumbs .thumb img")) == 24, 30)
        check(thumbs, "a thumbnail for each of the 24 frames")
        shot("job")

        # ---- the frame page's image and a thumbnail against the fetched frame
        fetched = os.path.join(a.work, "fetched")
        locus("fetch", job, fetched)
        frame = np.asarray(Image.open(os.path.join(fetched, "shot_0005.png")).convert("RGB"), dtype=np.int32)
        pixels_js = """
            const img = arguments[0];
            const c = document.createElement('canvas');
            c.width = img.naturalWidth; c.height = img.naturalHeight;
            const g = c.getContext('2d');
            g.drawImage(img, 0, 0);
            const d = g.getImageData(0, 0, c.width, c.height).data;
            let s = ''; for (let i = 0; i < d.length; i += 8192)
              s += String.fromCharCode.apply(null, d.subarray(i, i + 8192));
            return [c.width, c.height, btoa(s)];"""

        def pixels(img):
            w, h, data = driver.execute_script(pixels_js, img)
            rgba = np.frombuffer(base64.b64decode(data), dtype=np.uint8).reshape(h, w, 4)
            return rgba[:, :, :3].astype(np.int32)

        thumb = driver.find_element(By.CSS_SELECTOR, '#thumbs .thumb[data-frame="5"] img')
        t = pixels(thumb)
        k = -(-frame.shape[1] // 160)
        h, w = -(-frame.shape[0] // k), -(-frame.shape[1] // k)
        box = np.zeros((h, w, 3))
        for y in range(h):
            for x in range(w):
                box[y, x] = frame[y * k:(y + 1) * k, x * k:(x + 1) * k].reshape(-1, 3).mean(axis=0)
        err = np.abs(t - box).max() if t.shape == box.shape else 999
        check(err <= 2, f"thumbnail {t.shape[1]}x{t.shape[0]} within 2/255 of a {k}x{k} box filter "
                        f"(max {err:.2f}/255)")
        driver.get(a.url + "/#/frame/" + job + "/5")
        img = wait_for(lambda: driver.execute_script(
            "const i = document.getElementById('frame-image'); return i && i.complete && "
            "i.naturalWidth > 0 && i;"), 15)
        shown = pixels(img) if img else None
        same = shown is not None and shown.shape == frame.shape and int(np.abs(shown - frame).max()) == 0
        if not check(same, "the frame page's image equals the fetched frame (max error 0)",
                     None if shown is None else f"{shown.shape} vs {frame.shape}, max "
                     f"{np.abs(shown - frame).max() if shown.shape == frame.shape else '-'}"):
            if shown is not None:
                Image.fromarray(shown.astype(np.uint8)).save(os.path.join(a.out, "frame-as-shown.png"))
        wait_for(lambda: driver.find_element(By.ID, "frame-stats").text, 10)
        shot("frame")

        # ---- the band map of the frame whose band hung
        ev = hung[0]
        driver.get(a.url + f"/#/job/{job}/{ev['frame']}")
        strips = wait_for(lambda: len(driver.find_elements(By.CSS_SELECTOR, "#bandmap .strip")) == 16
                          and driver.find_elements(By.CSS_SELECTOR, "#bandmap .strip"), 15)
        check(strips, "the band map has one strip per band (16)")
        marked = [s.get_attribute("data-band") for s in (strips or []) if "marked" in s.get_attribute("class")]
        check(str(ev["band"]) in marked, f"the hung band {ev['band']} of frame {ev['frame']} is marked",
              marked)
        drawn = driver.execute_script(
            "const c = document.getElementById('row-costs'); if (!c) return 0;"
            "const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;"
            "let n = 0; for (let i = 3; i < d.length; i += 4) n += d[i] > 0; return n;")
        check(drawn > 0, "the predicted cost per row is drawn beside the band map")
        costs = [float(s.get_attribute("data-cost")) for s in strips or []]
        times = [float(s.get_attribute("data-seconds")) for s in strips or []]
        if len(costs) == 16 and np.std(costs) > 0 and np.std(times) > 0:
            print(f"note: correlation of render time and predicted cost over the 16 bands: "
                  f"{np.corrcoef(costs, times)[0, 1]:.2f}")
        if strips:
            strips[0].click()
        wait_for(lambda: "Attempts" in driver.find_element(By.ID, "band-detail").text, 5)
        driver.execute_script("document.getElementById('bandmap').scrollIntoView();")
        shot("bandmap")

        # ---- a job with cost maps: while its frame renders, the job page
        # shows the map of the bands done so far (paused there, so that it
        # holds still: the image the API draws for them); once written, the
        # very picture the coordinator wrote (fetched with `locus fetch`)
        cost_job = locus("submit", a.scene, "--size", "96x72", "--bands", "24", "-o",
                         "cm_####.png", "--cost-map", "cmc_####.png").stdout.strip()
        # (int64 fields are strings in proto3's JSON)
        some = wait_for(lambda: int(api(f"jobs/{cost_job}")["bands_done"]) >= 2, 20, 0.02)
        locus("pause", cost_job)
        # Settled: no lease left, and the count of bands done the same for
        # a second (a result in flight when the job paused is still kept).
        last = {"done": -1}

        def settled():
            j = api(f"jobs/{cost_job}")
            done = int(j["bands_done"])
            steady = int(j["bands_running"]) == 0 and done == last["done"]
            last["done"] = done
            return steady
        wait_for(settled, 20, 1.0)
        status = api(f"jobs/{cost_job}")
        in_progress = some and int(status["frames_done"]) == 0
        check(in_progress, f"the cost-map job paused with its frame in progress "
                           f"({status['bands_done']} of 24 bands)")
        if in_progress:
            driver.get(a.url + f"/#/job/{cost_job}/1")
            img = wait_for(lambda: driver.execute_script(
                "const i = document.getElementById('cost-map'); return i && i.complete && "
                "i.naturalWidth > 0 && i.dataset.written === '0' && i;"), 15)
            req = urllib.request.Request(a.url + f"/api/v1/jobs/{cost_job}/frames/1/cost-map",
                                         headers={"Authorization": "Bearer " + ann})
            with urllib.request.urlopen(req, timeout=10) as r:
                bands_in = r.headers.get("X-Locus-Bands-In")
                drawn = np.asarray(Image.open(io.BytesIO(r.read())).convert("RGB"), dtype=np.int32)
            ok = img is not None and bands_in == str(int(status["bands_done"]))
            if check(ok, f"the page shows the map of the bands done so far ({bands_in} in)"):
                shown = pixels(img)
                check(shown.shape == drawn.shape and int(np.abs(shown - drawn).max()) == 0 and
                      drawn[:, :, :].max() > 0,
                      "it is the map the API draws of them (max error 0), not blank")
                heading = driver.find_element(By.CSS_SELECTOR, "#cost-box h2").text
                check(f"{int(status['bands_done'])} of 24 bands" in heading, "its title says how many",
                      heading)
                shot("costmap-in-progress")
        locus("resume", cost_job)
        done = wait_for(lambda: "succeeded" in locus("status", cost_job).stdout, 60, 0.5)
        check(done, f"the cost-map job {cost_job} succeeds")
        got = os.path.join(a.work, "fetched-cost")
        locus("fetch", cost_job, got)
        written = os.path.join(got, "cmc_0001.png")
        driver.get(a.url + f"/#/job/{cost_job}/1")
        img = wait_for(lambda: driver.execute_script(
            "const i = document.getElementById('cost-map'); return i && i.complete && "
            "i.naturalWidth > 0 && i.dataset.written === '1' && i;"), 15)
        if check(img and os.path.exists(written), "the job page shows the frame's cost map"):
            want = np.asarray(Image.open(written).convert("RGB"), dtype=np.int32)
            shown = pixels(img)
            check(shown.shape == want.shape and int(np.abs(shown - want).max()) == 0,
                  "the shown cost map equals the fetched one (max error 0)",
                  f"{shown.shape} vs {want.shape}")
            driver.execute_script("document.getElementById('cost-box').scrollIntoView();")
            shot("costmap")
        driver.get(a.url + f"/#/job/{job}/1")
        wait_for(lambda: driver.find_elements(By.CSS_SELECTOR, "#bandmap .strip"), 10)
        check(not driver.find_elements(By.ID, "cost-map"),
              "a job without cost maps shows none")

        driver.get(a.url + "/#/worker/w0002")
        wait_for(lambda: driver.find_elements(By.CSS_SELECTOR, "#worker-attempts tr td"), 10)
        shot("worker")

        # ---- a movie job (--movie): its page plays the movie the coordinator made
        render_job = locus("submit", a.scene, "--size", "64x48", "--frames", "1-4", "-o",
                           "mv_####.png", "--movie", "mv.mp4", "--fps", "4").stdout.strip()
        movie_job = wait_for(lambda: api(f"jobs/{render_job}")["movie_job"], 10)
        made = movie_job and wait_for(lambda: "succeeded" in locus("status", movie_job).stdout, 60, 0.5)
        check(made, f"the movie job {movie_job} of job {render_job} succeeds")
        driver.get(a.url + "/#/job/" + str(movie_job))
        shape = wait_for(lambda: driver.execute_script(
            "const v = document.getElementById('movie-player');"
            "return v && v.readyState >= 1 && [v.videoWidth, v.videoHeight, v.duration];"), 15)
        check(shape and shape[0] == 64 and shape[1] == 48 and abs(shape[2] - 1.0) < 0.1,
              f"the movie job's page plays its H.264 movie (64x48, 4 frames at 4 fps): {shape}",
              driver.execute_script("const v = document.getElementById('movie-player');"
                                    "return v && v.error && v.error.message;"))
        events = wait_for(lambda: "the movie mv.mp4 of job" in driver.find_element(By.ID, "events").text
                          and driver.find_element(By.ID, "events").text, 10) or ""
        epoch = driver.execute_script("return new Date(0).toLocaleTimeString();")
        check(events and not events.startswith(epoch),
              "its events say what it makes, at their times (not the epoch's)", events[:120])
        shot("movie")

        # ---- without a token: no data, on the page or from the API
        driver.execute_script("sessionStorage.clear();")
        driver.get(a.url + "/")
        asked = wait_for(lambda: driver.find_element(By.ID, "login").is_displayed(), 10)
        check(asked and job not in driver.find_element(By.TAG_NAME, "body").text,
              "without a token the page asks for one and shows no job")
        status, body = driver.execute_async_script(
            "const cb = arguments[arguments.length - 1];"
            "fetch('/api/v1/jobs').then(r => r.text().then(t => cb([r.status, t])));")
        check(status == 401 and job not in body, f"the API without a token: {status}, no job data")
        shot("login")
    finally:
        driver.quit()
    print(f"{passed} passed, {failed} failed; screenshots in {a.out}")
    return 0 if failed == 0 else 1


if __name__ == "__main__":
    sys.exit(main())
