// The Locus dashboard (issue #24): one page, four views (farm, job, frame,
// worker) chosen by the URL's fragment, fed by the coordinator's JSON API
// (docs/http-api.md). Everything shown is built with textContent and
// createElement, never HTML from data: a scene or worker name is text.
// The token lives in this tab's sessionStorage and goes in the
// Authorization header of every call; images are fetched the same way and
// shown from blob URLs. Updates: a poll every second with the farm's
// cursor, which answers "unchanged" for nothing when the farm is idle.
'use strict';

const POLL_MS = 1000;
let token = sessionStorage.getItem('locus-token') || '';
let version = 0;          // the farm's cursor
let view = null;          // the current view: {name, args, render(snapshot), cleanup}
let timer = null;

// ---------------------------------------------------------------- helpers

function el(tag, attrs, ...children) {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs || {})) {
    if (k === 'class') e.className = v;
    else if (k === 'text') e.textContent = v;
    else if (k.startsWith('on')) e.addEventListener(k.slice(2), v);
    else if (k === 'dataset') Object.assign(e.dataset, v);
    else if (k === 'style') {
      // Through the CSSOM: the Content-Security-Policy refuses style
      // attributes (style-src 'self').
      for (const decl of String(v).split(';')) {
        const at = decl.indexOf(':');
        if (at > 0) e.style.setProperty(decl.slice(0, at).trim(), decl.slice(at + 1).trim());
      }
    }
    else e.setAttribute(k, v);
  }
  for (const c of children) {
    if (c === null || c === undefined) continue;
    e.append(c instanceof Node ? c : document.createTextNode(String(c)));
  }
  return e;
}

const num = (v) => Number(v || 0);
const link = (href, text) => el('a', {href, text});
const stateTag = (s) => el('span', {class: 'state ' + s, text: s});

function fmtSeconds(s) {
  s = num(s);
  if (s < 60) return s.toFixed(1) + ' s';
  if (s < 3600) return Math.floor(s / 60) + ' min ' + Math.round(s % 60) + ' s';
  return Math.floor(s / 3600) + ' h ' + Math.round((s % 3600) / 60) + ' min';
}

function jobState(j) {
  return String(j.state || '').replace(/^JOB_STATE_/, '').toLowerCase();
}

function eta(j) {
  const done = num(j.bands_done), total = num(j.bands_total), t = num(j.seconds_elapsed);
  if (jobState(j) !== 'running' || done === 0 || done >= total) return '';
  return fmtSeconds(t / done * (total - done));
}

async function api(path, options) {
  const o = Object.assign({headers: {}}, options || {});
  o.headers['Authorization'] = 'Bearer ' + token;
  if (o.body !== undefined) o.headers['Content-Type'] = 'application/json';
  const r = await fetch('/api/v1/' + path, o);
  if (r.status === 401) {
    showLogin('The farm did not accept this token.');
    throw new Error('unauthenticated');
  }
  const type = r.headers.get('Content-Type') || '';
  if (!type.startsWith('application/json')) {
    if (!r.ok) throw new Error(r.status + ' ' + r.statusText);
    return r.blob();
  }
  const body = await r.json();
  if (!r.ok) throw new Error(body.error ? body.error.code + ': ' + body.error.message : r.status);
  return body;
}

// An image from the API, shown through a blob URL (an <img src> could not
// carry the token). Replaces the old URL of `img`, if any.
async function loadImage(img, path) {
  const blob = await api(path);
  const old = img.dataset.blob;
  img.src = URL.createObjectURL(blob);
  img.dataset.blob = img.src;
  if (old) URL.revokeObjectURL(old);
  await img.decode().catch(() => {});
  return img;
}

function setStatus(text, bad) {
  const s = document.getElementById('status');
  s.textContent = text;
  s.className = 'status' + (bad ? ' error' : '');
}

function showLogin(message) {
  document.getElementById('main').hidden = true;
  document.getElementById('login').hidden = false;
  document.getElementById('login-error').textContent = message || '';
}

async function act(path, body, what) {
  try {
    await api(path, {method: 'POST', body: JSON.stringify(body || {})});
    setStatus(what + ': done');
    version = 0;  // show the change at once
    poll();
  } catch (e) {
    setStatus(what + ': ' + e.message, true);
  }
}

// ---------------------------------------------------------------- farm

function farmView() {
  const main = document.getElementById('main');
  main.replaceChildren(
      el('h1', {text: 'Farm'}),
      el('h2', {text: 'Jobs'}),
      el('table', {id: 'jobs'},
         el('thead', {}, el('tr', {}, ...['job', 'owner', 'scene', 'priority', 'state',
                                          'progress', 'frames', 'elapsed', 'ETA', 'waiting']
                                          .map((h) => el('th', {text: h})))),
         el('tbody')),
      el('h2', {text: 'Workers'}),
      el('table', {id: 'workers'},
         el('thead', {}, el('tr', {}, ...['worker', 'name', 'tags', 'state', 'band',
                                          'bands done', 'last seen']
                                          .map((h) => el('th', {text: h})))),
         el('tbody')));
  return {
    render(farm) {
      const jobs = main.querySelector('#jobs tbody');
      jobs.replaceChildren(...(farm.jobs || []).slice().reverse().map((j) => {
        const done = num(j.bands_done), total = Math.max(1, num(j.bands_total));
        return el('tr', {dataset: {job: j.job_id}},
                  el('td', {}, link('#/job/' + encodeURIComponent(j.job_id), j.job_id)),
                  el('td', {text: j.owner || '-'}),
                  el('td', {class: 'wrap', text: j.scene_name}),
                  el('td', {class: 'num', text: j.priority}),
                  el('td', {}, stateTag(jobState(j))),
                  el('td', {class: 'progress'},
                     el('div', {class: 'bar', title: done + '/' + total + ' bands'},
                        el('div', {style: 'width:' + (100 * done / total).toFixed(1) + '%'})),
                     el('span', {class: 'muted', text: ' ' + done + '/' + num(j.bands_total)})),
                  el('td', {class: 'num frames', text: j.frames_done + '/' + j.frames_total}),
                  el('td', {class: 'num', text: fmtSeconds(j.seconds_elapsed)}),
                  el('td', {class: 'num', text: eta(j)}),
                  el('td', {class: 'wrap muted', text: j.waiting || j.error || ''}));
      }));
      const workers = main.querySelector('#workers tbody');
      workers.replaceChildren(...(farm.workers || []).map((w) => el('tr', {},
          el('td', {}, link('#/worker/' + encodeURIComponent(w.worker_id), w.worker_id)),
          el('td', {class: 'name', text: w.name}),
          el('td', {text: (w.tags || []).join(', ')}),
          el('td', {}, stateTag(w.state)),
          el('td', {text: w.job_id ? w.job_id + ' frame ' + w.frame + ' band ' + w.band : ''}),
          el('td', {class: 'num', text: w.bands_done}),
          el('td', {class: 'num', text: fmtSeconds(w.seconds_since_seen) + ' ago'}))));
    },
  };
}

// ---------------------------------------------------------------- job

// The band map of one frame: a strip per band, its height its rows, its
// colour its render time per row (the renderer's own seconds for the band,
// without the network or the queue, over its rows: bands cut by predicted
// cost have different heights; pale: fast, dark red: slow); beside it the
// predicted cost of each row from the localization preview.
const renderSeconds = (b) => num((b.stats || {}).seconds_render);
const perRow = (b) => renderSeconds(b) / Math.max(1, b.y1 - b.y0);
function bandMap(frame, onPick) {
  const maxH = 420, scale = Math.min(2, maxH / Math.max(1, frame.height));
  const bands = frame.bands || [];
  const slowest = Math.max(1e-12, ...bands.map(perRow));
  const costliest = Math.max(1e-9, ...bands.map((b) => num(b.predicted_cost)));
  const map = el('div', {class: 'bandmap', id: 'bandmap'});
  for (const b of bands) {
    const h = Math.max(3, Math.round((b.y1 - b.y0) * scale));
    const t = perRow(b) / slowest;
    const colour = b.state === 'done'
        ? `rgb(${255}, ${Math.round(235 - 200 * t)}, ${Math.round(180 - 160 * t)})`
        : (b.state === 'running' ? '#9cc3ea' : '#cfcfcb');
    const attempts = (b.attempts || []).length;
    const retried = attempts > 1 || (b.attempts || []).some((a) => a.outcome && a.outcome !== 'done');
    const label = `band ${b.band}: ${b.state}` +
        (b.state === 'done' ? `, rendered in ${renderSeconds(b).toFixed(3)} s by ${b.worker_name}` : '') +
        (attempts > 1 ? `, ${attempts} attempts` : '');
    const strip = el('div', {class: 'strip' + (retried ? ' marked' : ''), title: label,
                             dataset: {band: b.band, state: b.state, retried: retried ? '1' : '0',
                                       seconds: renderSeconds(b), cost: num(b.predicted_cost)},
                             style: `height:${h}px`, onclick: () => onPick(b)},
                     el('div', {class: 'time', style: `background:${colour}`},
                        h >= 12 ? el('span', {text: label}) : null),
                     el('div', {class: 'cost'},
                        el('div', {style: `width:${(100 * num(b.predicted_cost) / costliest)
                                                  .toFixed(1)}%`})));
    map.append(strip);
  }
  const costs = frame.row_costs || [];
  const side = el('canvas', {id: 'row-costs', width: 120,
                             height: Math.max(1, Math.round(frame.height * scale)),
                             title: 'predicted cost per row'});
  if (costs.length) {
    const g = side.getContext('2d');
    const top = Math.max(1e-9, ...costs);
    g.fillStyle = '#5b7fa8';
    costs.forEach((c, y) => g.fillRect(0, y * scale, 120 * c / top, Math.max(1, scale)));
  }
  return el('div', {class: 'row'},
            el('div', {}, el('div', {class: 'legend',
                                     text: 'render time per row (pale fast, red slow) | ' +
                                           'predicted cost of the band; dashed: retried or hung'}),
               map),
            el('div', {}, el('div', {class: 'legend',
                                     text: costs.length ? 'predicted cost per row'
                                                        : 'no cost prediction (equal bands)'}),
               side));
}

async function bandDetail(job, frame, b, box) {
  const rows = [['rows', `${b.y0}-${b.y1}`], ['state', b.state],
                ['worker', b.worker_name || '-'],
                ['render seconds', renderSeconds(b).toFixed(3)],
                ['lease to result, seconds', num(b.seconds).toFixed(3)],
                ['predicted cost', num(b.predicted_cost).toFixed(1)]];
  const s = b.stats || {};
  if (b.state === 'done') {
    rows.push(['rays (eye, reflected, refracted, shadow)',
               [s.rays_eye, s.rays_reflected, s.rays_refracted, s.rays_shadow].map(num).join(', ')],
              ['ray-traced pixels',
               (100 * num(s.pixels_ray_traced) / Math.max(1, num(s.pixels_total))).toFixed(1) + '%'],
              ['shadow-volume tests', num(s.tests_shadow_volume)]);
  }
  const attempts = (b.attempts || []).map((a) =>
      `${a.lease_id} ${a.worker_name}: ${a.outcome || 'running'}${a.error ? ' (' + a.error + ')' : ''}`);
  box.replaceChildren(el('h2', {text: `Band ${b.band} of frame ${frame}`}),
                      el('table', {class: 'kv'}, ...rows.map(([k, v]) =>
                          el('tr', {}, el('td', {text: k}), el('td', {text: v})))),
                      el('h2', {text: 'Attempts'}), el('pre', {text: attempts.join('\n') || '-'}),
                      el('h2', {text: 'Log'}), el('pre', {id: 'band-log', text: '…'}));
  try {
    const logs = await api(`jobs/${encodeURIComponent(job)}/logs?frame=${frame}&band=${b.band}`);
    box.querySelector('#band-log').textContent =
        (logs.lines || []).map((l) => l.text).join('\n') || '(nothing logged)';
  } catch (e) {
    box.querySelector('#band-log').textContent = e.message;
  }
}

// `pinned`: the frame whose band map and image to show (#/job/J/F);
// otherwise the frame in progress.
function jobView(jobId, pinned) {
  const main = document.getElementById('main');
  const q = encodeURIComponent(jobId);
  const head = el('div');
  const thumbs = el('div', {class: 'thumbs', id: 'thumbs'});
  const partial = el('canvas', {class: 'partial', id: 'partial', width: 1, height: 1});
  const partialTitle = el('h2', {text: 'Frame in progress'});
  const mapBox = el('div');
  const detail = el('div', {class: 'detail', id: 'band-detail',
                            text: 'Click a band for its stats and log.'});
  const events = el('pre', {id: 'events'});
  // A job with cost maps (locus submit --cost-map; docs/cost-map.md): the
  // shown frame's map, the work its bands' workers counted per pixel.
  const costBox = el('div', {id: 'cost-box'});
  main.replaceChildren(head, el('h2', {text: 'Frames'}), thumbs,
                       el('div', {class: 'row'}, el('div', {}, partialTitle, partial),
                          el('div', {}, el('h2', {id: 'bandmap-title', text: 'Band map'}), mapBox),
                          detail),
                       costBox,
                       el('h2', {text: 'Events'}), el('div', {class: 'events'}, events));
  let after = 0, shownFrame = null, strips = {}, costShown = null;
  const thumbLoaded = new Set();
  const movieBox = el('div', {class: 'movie', id: 'movie'});

  // While the frame renders, the map of its bands done so far (redrawn as
  // bands come in: its scale is of those bands); once written, the file.
  async function showCostMap(j, f, frame) {
    if (!j.cost_map) {
      costBox.replaceChildren();
      return;
    }
    const done = (frame.bands || []).filter((b) => b.state === 'done').length;
    const key = `${f}:${frame.written ? 'written' : done}`;
    if (costShown === key) return;
    const img = el('img', {id: 'cost-map', class: 'costmap', alt: `cost map of frame ${f}`,
                           dataset: {written: frame.written ? '1' : '0', bands: done}});
    costBox.replaceChildren(
        el('h2', {text: frame.written ? `Cost map of frame ${f}`
                                      : `Cost map of frame ${f}: ${done} of ` +
                                        `${(frame.bands || []).length} bands so far`}),
        el('div', {class: 'legend',
                   text: 'rays and shadow-volume tests per pixel, as counted by the bands\' ' +
                         'workers (log scale; the scale at the bottom); cyan outline: spans ' +
                         'ray traced'}),
        img);
    costShown = key;
    if (done === 0 && !frame.written) return;
    try {
      await loadImage(img, `jobs/${q}/frames/${f}/cost-map`);
    } catch (e) {
      costShown = null;  // written meanwhile, or not yet readable: the next poll tries again
    }
  }

  async function renderFrame(j, f) {
    const frame = await api(`jobs/${q}/frames/${f}`);
    partialTitle.textContent = frame.written ? `Frame ${f} (written)` : `Frame ${f} in progress`;
    const map = bandMap(frame, (b) => bandDetail(jobId, f, b, detail));
    document.getElementById('bandmap-title').textContent = `Band map of frame ${f}`;
    mapBox.replaceChildren(map);
    // The partial image: bands done drawn as they arrive, others grey.
    if (partial.width !== frame.width || partial.height !== frame.height || shownFrame !== f) {
      partial.width = frame.width;
      partial.height = frame.height;
      const g = partial.getContext('2d');
      g.fillStyle = '#9a9a96';
      g.fillRect(0, 0, frame.width, frame.height);
      strips = {};
      shownFrame = f;
    }
    await showCostMap(j, f, frame);
    const g = partial.getContext('2d');
    if (frame.written) {
      if (!strips.whole) {
        const img = await loadImage(new Image(), `jobs/${q}/frames/${f}/image`);
        g.drawImage(img, 0, 0);
        strips.whole = true;
      }
      return;
    }
    for (const b of frame.bands || []) {
      if (b.state !== 'done' || strips[b.band]) continue;
      try {
        const img = await loadImage(new Image(), `jobs/${q}/frames/${f}/bands/${b.band}/image`);
        g.drawImage(img, 0, b.y0);
        strips[b.band] = true;
      } catch (e) { /* its frame was written meanwhile: shown at the next poll */ }
    }
  }

  return {
    async render(farm) {
      const j = (farm.jobs || []).find((x) => x.job_id === jobId) ||
                await api(`jobs/${q}`);
      const st = jobState(j);
      head.replaceChildren(
          el('h1', {}, 'Job ' + j.job_id + ' ', stateTag(st)),
          el('p', {class: 'muted', id: 'job-summary',
                   text: `${j.scene_name}, ${j.width}x${j.height}, frames ${j.frame_first}-` +
                         `${j.frame_last}, ${j.bands_per_frame} bands per frame; owner ` +
                         `${j.owner || '-'}, priority ${j.priority}; ${num(j.bands_done)}/` +
                         `${num(j.bands_total)} bands, ${j.frames_done}/${j.frames_total} ` +
                         `frames, ${fmtSeconds(j.seconds_elapsed)}` +
                         (eta(j) ? `, ETA ${eta(j)}` : '') +
                         (j.waiting ? `; ${j.waiting}` : '') + (j.error ? `; ${j.error}` : '')}),
          el('div', {class: 'actions'},
             el('button', {id: 'pause', onclick: () => act(`jobs/${q}/pause`, {}, 'pause')}, 'Pause'),
             el('button', {id: 'resume', onclick: () => act(`jobs/${q}/resume`, {}, 'resume')},
                'Resume'),
             el('button', {id: 'cancel', onclick: () => act(`jobs/${q}/cancel`, {}, 'cancel')},
                'Cancel'),
             el('button', {id: 'retry', onclick: () => act(`jobs/${q}/retry`, {}, 'retry')}, 'Retry'),
             el('button', {id: 'requeue', onclick: () => act(`jobs/${q}/requeue`, {}, 'requeue')},
                'Requeue all'),
             ' priority ',
             el('input', {id: 'priority-value', type: 'number', min: 0, max: 100,
                          value: j.priority, style: 'width:4em'}),
             el('button', {id: 'priority', onclick: () => act(`jobs/${q}/priority`, {
               priority: Number(document.getElementById('priority-value').value)}, 'priority')},
                'Set')));
      if (j.kind === 'movie') {
        await renderMovie(j);
      } else {
        await renderFrames(j);
      }
      const ev = await api(`jobs/${q}/events?after=${after}`);
      for (const e of ev.events || []) {
        events.append(new Date(num(e.unix_seconds) * 1000).toLocaleTimeString() + '  ' + e.text + '\n');
        after = Math.max(after, num(e.seq));
      }
    },
  };

  // A movie job (docs/farm.md "Movies"): no frames nor bands of its own;
  // the movie, once made, played from the farm.
  async function renderMovie(j) {
    if (!movieBox.isConnected) {
      main.replaceChildren(head, el('h2', {text: 'Movie'}), movieBox,
                           el('h2', {text: 'Events'}), el('div', {class: 'events'}, events));
    }
    document.getElementById('job-summary').textContent =
        `The movie ${j.movie} of the frames of job ${(j.after || [])[0] || '?'} at ${j.fps} fps,` +
        ` made by the coordinator; owner ${j.owner || '-'}; ${fmtSeconds(j.seconds_elapsed)}` +
        (j.waiting ? `; ${j.waiting}` : '') + (j.error ? `; ${j.error}` : '');
    if (jobState(j) !== 'succeeded') {
      movieBox.replaceChildren(el('p', {class: 'muted', text: 'Not made yet.'}));
      delete movieBox.dataset.loaded;
      return;
    }
    if (movieBox.dataset.loaded) return;
    movieBox.dataset.loaded = '1';
    const url = URL.createObjectURL(await api(`jobs/${q}/frames/1/movie`));
    const gif = String(j.movie).toLowerCase().endsWith('.gif');
    const player = gif ? el('img', {id: 'movie-player', alt: j.movie})
                       : el('video', {id: 'movie-player', controls: '', loop: ''});
    player.src = url;
    movieBox.replaceChildren(player, el('p', {},
        el('a', {href: url, download: j.movie, text: 'Download ' + j.movie})));
  }

  async function renderFrames(j) {
      if (j.movie_job) {
        const p = document.getElementById('job-summary');
        p.append('; movie ', link(`#/job/${encodeURIComponent(j.movie_job)}`, j.movie),
                 ` (job ${j.movie_job})`);
      }
      // Thumbnails: every frame, filled in as it is written.
      const written = new Set((j.frames_written || []).map(Number));
      if (thumbs.children.length !== num(j.frames_total)) {
        thumbs.replaceChildren();
        for (let f = j.frame_first; f <= j.frame_last; ++f) {
          thumbs.append(el('div', {class: 'thumb', dataset: {frame: f}},
                           el('div', {class: 'ph'}),
                           link(`#/frame/${q}/${f}`, 'frame ' + f), ' ',
                           link(`#/job/${q}/${f}`, 'bands')));
        }
      }
      for (const t of thumbs.children) {
        const f = Number(t.dataset.frame);
        if (!written.has(f) || thumbLoaded.has(f)) continue;
        thumbLoaded.add(f);
        const img = el('img', {alt: 'frame ' + f});
        loadImage(img, `jobs/${q}/frames/${f}/thumbnail`)
            .then(() => t.firstChild.replaceWith(img))
            .catch(() => thumbLoaded.delete(f));
      }
      // The frame in progress: the lowest unwritten frame, else the last.
      let f = j.frame_last;
      for (let k = j.frame_first; k <= j.frame_last; ++k) {
        if (!written.has(k)) { f = k; break; }
      }
      if (Number.isInteger(pinned) && pinned >= j.frame_first && pinned <= j.frame_last) f = pinned;
      await renderFrame(j, f);
  }
}

// ---------------------------------------------------------------- frame

function frameView(jobId, frame) {
  const main = document.getElementById('main');
  const q = encodeURIComponent(jobId);
  const img = el('img', {class: 'full', id: 'frame-image', alt: `frame ${frame}`});
  const stats = el('table', {class: 'kv', id: 'frame-stats'});
  const bands = el('table', {id: 'frame-bands'});
  main.replaceChildren(el('h1', {}, link(`#/job/${q}`, jobId), ` frame ${frame}`),
                       el('div', {class: 'row'}, img,
                          el('div', {}, el('h2', {text: 'Stats'}), stats)),
                       el('h2', {text: 'Bands'}), bands);
  let loaded = false;
  return {
    async render() {
      const f = await api(`jobs/${q}/frames/${frame}`);
      if (f.written && !loaded) {
        await loadImage(img, `jobs/${q}/frames/${frame}/image`);
        loaded = true;
      }
      const sum = {};
      let seconds = 0;
      for (const b of f.bands || []) {
        seconds += num(b.seconds);
        for (const [k, v] of Object.entries(b.stats || {})) {
          if (typeof v !== 'string' || !isNaN(Number(v))) sum[k] = (sum[k] || 0) + num(v);
        }
      }
      const share = 100 * (sum.pixels_ray_traced || 0) / Math.max(1, sum.pixels_total || 0);
      stats.replaceChildren(...[
        ['written', f.written ? f.file_name : 'not yet'],
        ['band-seconds', seconds.toFixed(3)],
        ['render CPU seconds', (sum.seconds_render_cpu || 0).toFixed(3)],
        ['eye rays', sum.rays_eye || 0], ['reflected rays', sum.rays_reflected || 0],
        ['refracted rays', sum.rays_refracted || 0], ['shadow rays', sum.rays_shadow || 0],
        ['ray-traced pixels', share.toFixed(1) + '%'],
        ['shadow-volume tests', sum.tests_shadow_volume || 0],
      ].map(([k, v]) => el('tr', {}, el('td', {text: k}), el('td', {class: 'num', text: v}))));
      bands.replaceChildren(
          el('tr', {}, ...['band', 'rows', 'state', 'worker', 'seconds', 'attempts',
                           'predicted cost'].map((h) => el('th', {text: h}))),
          ...(f.bands || []).map((b) => el('tr', {},
              el('td', {text: b.band}), el('td', {text: `${b.y0}-${b.y1}`}),
              el('td', {}, stateTag(b.state)), el('td', {text: b.worker_name || ''}),
              el('td', {class: 'num', text: num(b.seconds).toFixed(3)}),
              el('td', {class: 'num', text: (b.attempts || []).length}),
              el('td', {class: 'num', text: num(b.predicted_cost).toFixed(1)}))));
    },
  };
}

// ---------------------------------------------------------------- worker

function workerView(workerId) {
  const main = document.getElementById('main');
  const head = el('div'), attempts = el('table', {id: 'worker-attempts'});
  const failures = el('pre', {id: 'worker-failures'}), logs = el('pre', {id: 'worker-logs'});
  main.replaceChildren(head, el('h2', {text: 'Bands'}), attempts, el('h2', {text: 'Failures'}),
                       failures, el('h2', {text: 'Log lines'}), logs);
  return {
    async render() {
      const w = await api('workers/' + encodeURIComponent(workerId));
      const info = w.info || {};
      head.replaceChildren(el('h1', {}, 'Worker ' + w.worker_id + ' ',
                              stateTag(info.state || 'gone')),
                           el('p', {class: 'muted', text: (info.name || '') + (info.tags &&
                               info.tags.length ? '; tags ' + info.tags.join(', ') : '') +
                               (info.name ? `; ${info.bands_done} bands done` : '')}));
      attempts.replaceChildren(
          el('tr', {}, ...['lease', 'job', 'frame', 'band', 'outcome', 'seconds']
                           .map((h) => el('th', {text: h}))),
          ...(w.attempts || []).map((a) => el('tr', {},
              el('td', {text: a.lease_id}),
              el('td', {}, link('#/job/' + encodeURIComponent(a.job_id), a.job_id)),
              el('td', {text: a.frame}), el('td', {text: a.band}),
              el('td', {text: a.outcome || 'running'}),
              el('td', {class: 'num', text: num(a.ended_at) ? (num(a.ended_at) -
                  num(a.started_at)).toFixed(3) : ''}))));
      failures.textContent = (w.attempts || [])
          .filter((a) => a.outcome && a.outcome !== 'done')
          .map((a) => `${a.job_id} frame ${a.frame} band ${a.band}: ${a.outcome} ${a.error}`)
          .join('\n') || '(none)';
      logs.textContent = (w.logs || []).map((l) => `${l.lease_id}: ${l.text}`).join('\n') ||
                         '(nothing logged)';
    },
  };
}

// ---------------------------------------------------------------- router

function route() {
  const hash = decodeURIComponent(location.hash.slice(1));
  const parts = hash.split('/').filter((p) => p);
  document.getElementById('main').hidden = false;
  document.getElementById('login').hidden = true;
  if (parts[0] === 'job' && parts[1]) {
    view = jobView(parts[1], parts[2] !== undefined ? Number(parts[2]) : undefined);
  }
  else if (parts[0] === 'frame' && parts[1] && parts[2]) view = frameView(parts[1], Number(parts[2]));
  else if (parts[0] === 'worker' && parts[1]) view = workerView(parts[1]);
  else view = farmView();
  version = 0;
  poll();
}

let polling = false;
async function poll() {
  clearTimeout(timer);
  if (polling) return;
  polling = true;
  try {
    const farm = await api('farm?since=' + version);
    if (!farm.unchanged) {
      version = num(farm.version);
      await view.render(farm);
      setStatus('updated ' + new Date().toLocaleTimeString());
    }
  } catch (e) {
    if (e.message !== 'unauthenticated') setStatus(e.message, true);
  } finally {
    polling = false;
    timer = setTimeout(poll, POLL_MS);
  }
}

function start() {
  // A token in the fragment (#token=...: the embedded farm's link) is
  // kept for this tab and taken out of the address bar.
  const m = location.hash.match(/^#token=([^&]*)/);
  if (m) {
    token = decodeURIComponent(m[1]);
    sessionStorage.setItem('locus-token', token);
    history.replaceState(null, '', location.pathname + '#/');
  }
  document.getElementById('signin').addEventListener('click', () => {
    token = document.getElementById('token').value.trim();
    sessionStorage.setItem('locus-token', token);
    route();
  });
  window.addEventListener('hashchange', route);
  if (!token) showLogin('');
  else route();
}

document.addEventListener('DOMContentLoaded', start);
