#!/usr/bin/env bash
# tests/movie/run.sh BINDIR SOURCE_DIR: movies and notifications with the
# real binaries (issue #26 items 1, 2; CTest `movies`):
#   1 the README's demo command (deploy/local/demo.sh: 24 frames of
#     scenes/anim/glass_and_mirror.json on an embedded farm of 2 workers,
#     --movie anim.mp4): ffprobe reads 24 frames of 320x240 at 24 fps, H.264
#     in yuv420p; frames 1, 12 and 24 decoded match their PNGs with PSNR
#     >= 35 dB;
#   2 --workers 0 makes .webm (VP9, --fps 12) and .gif movies, ffprobe reads
#     their frame counts; a bad --movie is refused naming it;
#   3 a coordinator process on 127.0.0.1 with --notify-urls and
#     --notify-cmd, 2 workers: `locus submit --movie --notify-url --wait`
#     fetches the frames and the movie; `locus status` shows the movie job,
#     `locus events` its making; a receiver on 127.0.0.1 (Python's
#     http.server) gets the movie job's final status as JSON; the command
#     ran with the job in its environment; a URL outside --notify-urls is
#     refused.
# Loopback only. Prints one line per check and "N passed, M failed".
set -uo pipefail
[ $# -eq 2 ] || { echo "usage: $0 BINDIR SOURCE_DIR" >&2; exit 2; }
bin=$(cd "$1" && pwd) src=$(cd "$2" && pwd) || exit 2
py=/usr/bin/python3
for tool in ffmpeg ffprobe "$py"; do
  command -v "$tool" >/dev/null || { echo "FAILED: $tool is missing (deploy/local/install-deps.sh)"; exit 1; }
done
tmp=$(mktemp -d)
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done
  wait 2>/dev/null
  if [ -n "${KEEP:-}" ]; then echo "kept $tmp"; else rm -rf "$tmp"; fi
}
trap cleanup EXIT
passed=0 failed=0
ok() { echo "ok: $1"; passed=$((passed + 1)); }
bad() { echo "FAILED: $1"; failed=$((failed + 1)); }
check() { # check DESCRIPTION CMD...
  local what=$1
  shift
  if "$@"; then ok "$what"; else bad "$what"; fi
}
# probe FILE: "codec,width,height,pix_fmt,rate,frames" of its video stream.
probe() {
  ffprobe -v error -select_streams v:0 -count_frames \
    -show_entries stream=codec_name,width,height,pix_fmt,r_frame_rate,nb_read_frames -of csv=p=0 "$1"
}
# psnr MOVIE INDEX PNG: the decoded frame INDEX (from 0) against the PNG, in dB.
psnr() {
  ffmpeg -v error -y -i "$1" -vf "select=eq(n\,$2),format=rgb24" -frames:v 1 "$tmp/decoded.png" &&
    "$py" - "$tmp/decoded.png" "$3" <<'EOF'
import sys
import numpy as np
from PIL import Image
a = np.asarray(Image.open(sys.argv[1]).convert("RGB"), dtype=float)
b = np.asarray(Image.open(sys.argv[2]).convert("RGB"), dtype=float)
assert a.shape == b.shape, (a.shape, b.shape)
mse = ((a - b) ** 2).mean()
print("inf" if mse == 0 else "%.2f" % (10 * np.log10(255.0 ** 2 / mse)))
EOF
}
at_least() { "$py" -c "import sys; sys.exit(0 if float('$1') >= float('$2') else 1)"; }

cd "$tmp"
# ---- 1: the demo's command (deploy/local/demo.sh), into out/
"$bin/locus" render "$src/scenes/anim/glass_and_mirror.json" --frames 1-24 --workers 2 \
  -o out/anim_####.png --movie out/anim.mp4 >demo.log 2>&1
check "the demo renders 24 frames and out/anim.mp4" test -s out/anim.mp4 -a -s out/anim_0024.png
got=$(probe out/anim.mp4)
check "ffprobe: H.264, 320x240, yuv420p, 24 fps, 24 frames ($got)" test "$got" = "h264,320,240,yuv420p,24/1,24"
for i in 1 12 24; do
  db=$(psnr out/anim.mp4 $((i - 1)) "$(printf 'out/anim_%04d.png' $i)")
  check "frame $i decoded matches its PNG: PSNR $db dB >= 35" at_least "${db:-0}" 35
done

# ---- 2: other formats, in process
"$bin/locus" render "$src/scenes/anim/glass_and_mirror.json" --frames 1-6 --size 160x120 --workers 0 \
  -o w/a_####.png --movie w/a.webm --fps 12 >w.log 2>&1
got=$(probe w/a.webm)
check "webm: VP9 160x120 yuv420p, 12 fps, 6 frames ($got)" test "$got" = "vp9,160,120,yuv420p,12/1,6"
"$bin/locus" render "$src/scenes/anim/glass_and_mirror.json" --frames 1-5 --size 81x61 --workers 0 \
  -o g/a_####.png --movie g/a.gif >g.log 2>&1
got=$(probe g/a.gif)
check "gif: 81x61, 5 frames ($got)" test "$(echo "$got" | cut -d, -f1-3,6)" = "gif,81,61,5"
if "$bin/locus" render "$src/scenes/anim/glass_and_mirror.json" --frames 1-2 --workers 0 \
  -o x/a_####.exr --movie x/a.mp4 >x.log 2>&1; then
  bad "a movie of EXR frames was not refused"
else
  check "a movie of EXR frames is refused, naming --movie" grep -q -- "--movie x/a.mp4: .*PNG or TIFF" x.log
fi

# ---- 3: a farm of processes: submit --movie --notify-url --wait, status, events
port() { "$py" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'; }
hook_port=$(port)
mkdir -p hooks
# The receiver: each POST's body to hooks/N.json, answers 204.
"$py" - "$hook_port" "$tmp/hooks" >receiver.log 2>&1 <<'EOF' &
import http.server, os, sys
port, out = int(sys.argv[1]), sys.argv[2]
class Hook(http.server.BaseHTTPRequestHandler):
    def do_POST(self):
        body = self.rfile.read(int(self.headers.get("Content-Length", 0)))
        n = len(os.listdir(out))
        with open(os.path.join(out, "%d.json" % n), "wb") as f:
            f.write(body)
        self.send_response(204)
        self.end_headers()
http.server.HTTPServer(("127.0.0.1", port), Hook).serve_forever()
EOF
pids+=($!)
"$bin/locus-coordinator" --listen 127.0.0.1:0 --data "$tmp/data" --insecure --no-fsync \
  --notify-urls "http://127.0.0.1:$hook_port/hooks" \
  --notify-cmd "echo \"\$LOCUS_JOB_ID \$LOCUS_JOB_STATE \$LOCUS_JOB_KIND\" >>'$tmp/told'" \
  >coord.out 2>coord.log &
pids+=($!)
farm=
for _ in $(seq 200); do
  p=$(sed -n 's/^listening on port //p' coord.out)
  [ -n "$p" ] && farm=127.0.0.1:$p && break
  sleep 0.05
done
[ -n "$farm" ] || { echo "FAILED: the coordinator did not start"; cat coord.log; exit 1; }
for i in 1 2; do
  "$bin/locus-worker" --coordinator "$farm" --threads 1 2>"worker$i.log" &
  pids+=($!)
done
export LOCUS_FARM=$farm
"$bin/locus" submit "$src/scenes/anim/glass_and_mirror.json" --frames 1-6 --size 96x72 \
  -o farm/s_####.png --movie farm/s.mp4 --fps 6 --notify-url "http://127.0.0.1:$hook_port/hooks/done" \
  --wait >submit.out 2>submit.err
rc=$?
check "submit --movie --wait exits 0 with the frames and the movie fetched" \
  test $rc -eq 0 -a -s farm/s_0006.png -a -s farm/s.mp4
render_job=$(head -1 submit.out)
movie_job=$(sed -n 's/^locus: job \(j[0-9]*\) makes the movie .*after it$/\1/p' submit.err)
check "submit names the movie job ($movie_job) after the render job ($render_job)" test -n "$movie_job" -a -n "$render_job"
got=$(probe farm/s.mp4)
check "the farm's movie: 96x72 at 6 fps, 6 frames ($got)" test "$got" = "h264,96,72,yuv420p,6/1,6"
"$bin/locus" status "$render_job" >status.txt 2>&1
check "status of the render job names its movie job" grep -q "movie    s.mp4 at 6 fps, by job $movie_job" status.txt
"$bin/locus" status "$movie_job" >status.txt 2>&1
check "status of the movie job: succeeded, the movie of $render_job" \
  grep -q "movie    s.mp4 of the frames of job $render_job, at 6 fps" status.txt
"$bin/locus" events "$movie_job" >events.txt 2>&1
check "events of the movie job show it made" grep -q "making the movie s.mp4 of frames 1-6 of job $render_job" events.txt
for _ in $(seq 100); do [ -s hooks/0.json ] && break; sleep 0.05; done
check "the receiver got the movie job's final status as JSON" \
  "$py" -c "import json,sys; j=json.load(open('hooks/0.json')); sys.exit(0 if j['job_id']=='$movie_job' and j['state']=='JOB_STATE_SUCCEEDED' and j['kind']=='movie' else 1)"
for _ in $(seq 100); do grep -q "$movie_job" told 2>/dev/null && break; sleep 0.05; done
check "--notify-cmd ran for both jobs with the job in its environment" \
  grep -qx "$render_job succeeded render" told
check "... and for the movie job" grep -qx "$movie_job succeeded movie" told
if "$bin/locus" submit "$src/scenes/anim/glass_and_mirror.json" -o n.png \
  --notify-url "http://127.0.0.1:$hook_port/elsewhere" >refused.out 2>refused.err; then
  bad "a notify URL outside --notify-urls was accepted"
else
  check "a notify URL outside --notify-urls is refused, naming the flag" grep -q -- "--notify-urls" refused.err
fi

echo "$passed passed, $failed failed"
if [ "$failed" -ne 0 ]; then
  for f in demo.log coord.log submit.err; do echo "---- $f"; tail -20 "$f"; done
  exit 1
fi
