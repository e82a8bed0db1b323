"""The design page itself: the editable fields and the HTML/JavaScript served at ``/``."""

from __future__ import annotations

import json

from starsense.web.jobs import MAX_FRAMES

__all__ = ["FIELDS", "page_html"]

#: section ("" = top level) -> (TOML key, label, input step)
FIELDS: dict[str, list[tuple[str, str, str]]] = {
    "": [("exposure_s", "exposure (s)", "any")],
    "optics": [
        ("focal_length_m", "focal length (m)", "any"),
        ("aperture_m", "aperture (m)", "any"),
        ("transmission", "transmission", "any"),
    ],
    "detector": [
        ("columns", "columns", "1"),
        ("rows", "rows", "1"),
        ("pixel_pitch_m", "pixel pitch (m)", "any"),
        ("psf_sigma_px", "PSF sigma (px)", "any"),
        ("qe_mean", "mean QE", "any"),
        ("read_noise_e", "read noise (e-)", "any"),
        ("gain_counts_per_e", "gain (counts/e-)", "any"),
        ("bit_depth", "bit depth", "1"),
        ("full_well_e", "full well (e-)", "any"),
    ],
    "detection": [
        ("lit_pixel_counts", "lit pixel (counts)", "any"),
        ("min_pixels", "min pixels", "1"),
        ("min_integrated_counts", "integrated (counts)", "any"),
    ],
}

#: the headline rows shown (trade row key, label, decimals)
_HEADLINE = [
    ("fov_width_deg", "field width (deg)", 2),
    ("pixel_scale_arcsec", "pixel scale (arcsec)", 2),
    ("limiting_magnitude", "limiting magnitude", 2),
    ("stars_median", "stars in field, median", 0),
    ("nea_cross", "NEA cross (arcsec)", 3),
    ("nea_roll", "NEA roll (arcsec)", 3),
    ("nea_over_limit_cross", "NEA / limit, cross", 1),
    ("availability_lis_rest", "lost in space at rest", 3),
    ("availability_lis_rate", "lost in space at the rate", 3),
    ("fastest_99", "fastest rate keeping 99 % (deg/s)", 2),
    ("budget_total_cross", "budget total, cross (arcsec)", 3),
]

_CSS = """
body{font-family:system-ui,sans-serif;margin:1.2em;color:#222}
h1{font-size:1.3em;margin:0 0 .6em} .cols{display:flex;gap:2em;align-items:flex-start}
fieldset{border:1px solid #ccc;margin:0 0 .8em;padding:.4em .8em}
label{display:grid;grid-template-columns:11em 9em;gap:.5em;margin:.2em 0;font-size:.9em}
input{font:inherit;width:9em} .err{color:#b00020;font-size:.8em;display:block;min-height:0}
table{border-collapse:collapse;font-size:.9em} td,th{padding:.15em .6em;text-align:right}
td:first-child,th:first-child{text-align:left} tr:nth-child(even){background:#f4f4f4}
#status{font-size:.85em;color:#555;min-height:1.2em} button{margin:.2em .4em .2em 0}
"""

_JS = """
const FIELDS = %(fields)s, HEAD = %(head)s;
let base = null, pins = [], last = null, timer = null, seq = 0;
const key = (s, n) => s ? s + '.' + n : n;
function documentNow() {
  const d = JSON.parse(JSON.stringify(base));
  for (const [s, list] of Object.entries(FIELDS)) for (const [n] of list) {
    const v = document.getElementById('f-' + key(s, n)).value;
    const num = Number(v);
    const val = (v.trim() === '' || isNaN(num)) ? v : num;
    if (s) { d[s] = d[s] || {}; d[s][n] = val; } else d[n] = val;
  }
  d.name = document.getElementById('f-name').value || d.name;
  return d;
}
function payload() {
  return {document: documentNow(), rate_deg_s: Number(document.getElementById('f-rate').value)};
}
function clearErrors() { document.querySelectorAll('.err').forEach(e => e.textContent = ''); }
function fmt(r, dec) {
  if (!r) return 'n/a';
  const t = r.value.toFixed(dec); return r.capped ? '>= ' + t : t;
}
async function post(url, body) {
  return fetch(url, {method: 'POST', headers: {'Content-Type': 'application/json'},
                     body: JSON.stringify(body)});
}
async function update() {
  const mine = ++seq; clearErrors();
  document.getElementById('status').textContent = 'computing...';
  const t0 = performance.now();
  const r = await post('/api/predict', payload());
  const j = await r.json();
  if (mine !== seq) return;
  if (!r.ok) {
    const where = j.field ? document.getElementById('e-' + j.field) : null;
    (where || document.getElementById('e-general')).textContent = j.error;
    document.getElementById('status').textContent = 'not computed: see the message';
    return;
  }
  last = j;
  for (const [k, , dec] of HEAD) {
    const cell = document.getElementById('v-' + k);
    cell.textContent = fmt(j.rows[k], dec);
    cell.dataset.value = j.rows[k] ? j.rows[k].value : '';
  }
  document.getElementById('warnings').textContent = j.warnings.join('; ');
  const img = document.getElementById('figure');
  if (j.figure_png) { img.src = 'data:image/png;base64,' + j.figure_png; img.hidden = false; }
  const dt = ((performance.now() - t0) / 1000).toFixed(1);
  document.getElementById('status').textContent = j.sensor + ': predicted in ' + dt + ' s';
}
function schedule() { clearTimeout(timer); timer = setTimeout(update, 400); }
function pin() {
  if (!last) return;
  pins.push({name: document.getElementById('f-name').value + ' #' + (pins.length + 1),
             rows: last.rows});
  const t = document.getElementById('pinned');
  let h = '<tr><th></th>' + pins.map(p => '<th class="pin">' + p.name + '</th>').join('') + '</tr>';
  for (const [k, label, dec] of HEAD)
    h += '<tr><td>' + label + '</td>' +
      pins.map(p => '<td>' + fmt(p.rows[k], dec) + '</td>').join('') + '</tr>';
  t.innerHTML = h;
}
async function download(url, fallback) {
  const r = await post(url, payload());
  if (!r.ok) {
    const j = await r.json();
    document.getElementById('e-general').textContent = j.error;
    return;
  }
  const blob = await r.blob();
  const cd = r.headers.get('Content-Disposition') || '';
  const m = cd.match(/filename="([^"]+)"/);
  const a = document.createElement('a');
  a.href = URL.createObjectURL(blob); a.download = m ? m[1] : fallback;
  document.body.appendChild(a); a.click(); a.remove();
}
async function verify() {
  const body = payload(); body.frames = Number(document.getElementById('f-frames').value);
  const r = await post('/api/verify', body); const j = await r.json();
  if (!r.ok) { document.getElementById('e-general').textContent = j.error; return; }
  const out = document.getElementById('verify');
  const poll = async () => {
    const s = await (await fetch('/api/verify/' + j.id)).json();
    if (s.error) { out.textContent = 'failed: ' + s.error; return; }
    if (s.finished) {
      const g = k => fmt(s.rows[k], 2);
      out.textContent = 'verified: measured/predicted cross ' + g('ratio_cross') +
        ', roll ' + g('ratio_roll') + '; solved at rest ' + g('lis_solved_rest') +
        ', wrong ' + g('lis_wrong_rest');
      return;
    }
    out.textContent = s.label + ' (' + s.done + '/' + s.total + ')';
    setTimeout(poll, 500);
  };
  poll();
}
async function start() {
  const j = await (await fetch('/api/base')).json(); base = j.document;
  for (const [s, list] of Object.entries(FIELDS)) for (const [n] of list) {
    const v = s ? (base[s] || {})[n] : base[n];
    document.getElementById('f-' + key(s, n)).value = v === undefined ? '' : v;
  }
  document.getElementById('f-name').value = base.name || 'design';
  document.querySelectorAll('input').forEach(i => i.addEventListener('input', schedule));
  update();
}
window.addEventListener('load', start);
"""


def _inputs() -> str:
    out = ['<fieldset><legend>design</legend><label>name <input id="f-name"></label>']
    out.append(
        '<label>slew rate (deg/s) <input id="f-rate" type="number" step="any" value="1"></label>'
    )
    out.append("</fieldset>")
    for section, names in FIELDS.items():
        out.append(f"<fieldset><legend>{section or 'exposure'}</legend>")
        for name, label, step in names:
            k = f"{section}.{name}" if section else name
            out.append(
                f'<label>{label} <input id="f-{k}" type="number" step="{step}"></label>'
                f'<span class="err" id="e-{k}"></span>'
            )
        out.append("</fieldset>")
    return "\n".join(out)


def page_html() -> str:
    """Return the page (one HTML document, its script and style inline)."""
    rows = "\n".join(f'<tr><td>{label}</td><td id="v-{k}">-</td></tr>' for k, label, _ in _HEADLINE)
    script = _JS % {"fields": json.dumps(FIELDS), "head": json.dumps(_HEADLINE)}
    return f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>starsense design</title>
<style>{_CSS}</style></head>
<body><h1>starsense design: what will this sensor do?</h1>
<div class="cols"><form id="form" onsubmit="return false">{_inputs()}</form>
<div><span class="err" id="e-general"></span><div id="status"></div>
<table id="headline"><tr><th>predicted (datasheet models, no frames)</th><th></th></tr>
{rows}</table><div id="warnings" class="err"></div>
<p><button id="pin" onclick="pin()">pin this design</button>
<button id="toml" onclick="download('/api/toml', 'design.toml')">download TOML</button>
<button id="json" onclick="download('/api/datasheet', 'datasheet.json')">download datasheet
JSON</button></p>
<p><button id="verify-btn" onclick="verify()">verify on rendered frames</button>
<input id="f-frames" type="number" value="20" min="1" max="{MAX_FRAMES}" step="1"
 style="width:5em"> frames per rate (at most {MAX_FRAMES})
<span id="verify"></span></p>
<img id="figure" alt="slew tolerance" hidden>
<h2 style="font-size:1.05em">pinned designs</h2><table id="pinned"></table></div></div>
<script>{script}</script></body></html>"""
