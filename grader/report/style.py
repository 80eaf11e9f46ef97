"""The pages' inline CSS (report and class view) and the class view's inline script.

Inline so a page is one self-contained file (offline, mailable, archivable). Status is never
shown by colour alone (text labels and symbols), so the pages work in greyscale print and for
colour-blind readers. Print: A4/Letter with 12 mm margins; wide tables wrap instead of being cut.
"""

CSS = """
:root{--ink:#1b1b1b;--muted:#555;--line:#c8c8c8;--pass:#0b6e2e;--partial:#8a5300;--fail:#a4161a;
--error:#5b3c88;--pending:#1f4e8c;--bg2:#f6f6f6}
*{box-sizing:border-box}
body{font:15px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;color:var(--ink);
margin:0 auto;max-width:1180px;padding:1.2rem}
h1{font-size:1.5rem;margin:.2rem 0}
h2{font-size:1.2rem;margin:1.6rem 0 .5rem;display:flex;justify-content:space-between;gap:1rem;
border-bottom:2px solid var(--ink)}
h3{font-size:1.05rem;margin:0 0 .3rem;display:flex;flex-wrap:wrap;gap:.3rem .7rem;align-items:baseline}
.sub{color:var(--muted);margin:0}
.scores{display:flex;flex-wrap:wrap;gap:.8rem;margin:1rem 0}
.score{border:1px solid var(--line);border-radius:6px;padding:.5rem .9rem;min-width:11rem}
.score b{display:block;font-size:1.6rem}
.score span{color:var(--muted);font-size:.85rem}
table{border-collapse:collapse;width:100%;margin:.3rem 0}
th,td{border-bottom:1px solid var(--line);padding:.35rem .5rem;text-align:left;vertical-align:top}
th{background:#f2f2f2;font-weight:600}tbody th{background:none}
caption{text-align:left;font-weight:600;padding:.3rem 0}
td.num,th.num{text-align:right;white-space:nowrap;font-variant-numeric:tabular-nums}
code,.id{font-family:ui-monospace,Menlo,Consolas,monospace;font-size:.85em;color:var(--muted)}
.badge{display:inline-block;border:1.5px solid currentColor;border-radius:999px;padding:0 .55rem;
font-size:.8rem;font-weight:700;white-space:nowrap}
.s-pass{color:var(--pass)}.s-partial{color:var(--partial)}.s-fail{color:var(--fail)}
.s-error{color:var(--error)}.s-pending{color:var(--pending)}
.pts{font-variant-numeric:tabular-nums;white-space:nowrap;color:var(--muted)}
.card{border:1px solid var(--line);border-left:6px solid currentColor;border-radius:6px;
padding:.7rem .9rem;margin:.8rem 0;color:var(--fail)}
.card.s-partial{color:var(--partial)}.card.s-error{color:var(--error)}.card.advisory{color:var(--muted)}
.card>*{color:var(--ink)}.card h3 .badge{color:inherit}
.card .measured{font-weight:600;margin:.2rem 0}
.runs{font-style:italic;margin:.2rem 0}
.card .feedback{margin:.2rem 0}
.hint{margin:.3rem 0;padding:.3rem .6rem;background:var(--bg2);border-radius:4px}
ul.items,ul.manual{list-style:none;padding:0;margin:.2rem 0}ul.manual>li{margin:.4rem 0}
ul.items>li{border-bottom:1px solid var(--line);padding:.25rem 0}
ul.items summary{cursor:pointer;display:flex;flex-wrap:wrap;gap:.2rem .7rem;align-items:baseline}
ul.items .line{display:flex;flex-wrap:wrap;gap:.2rem .7rem;align-items:baseline;padding-left:1.1rem}
ul.items .title{font-weight:600}
ul.items .fb{color:var(--muted);font-size:.9rem;flex:1 1 20rem}
.body{padding:.4rem 0 .6rem 1.1rem}
details.more{margin:.4rem 0}details.more>summary{cursor:pointer;color:#0b4f9c}
.tables{display:flex;flex-wrap:wrap;gap:.3rem 1.5rem;align-items:flex-start}
table.ev{width:auto;max-width:100%;font-size:.82rem;margin:.2rem 0}
table.ev th,table.ev td{padding:.1rem .45rem;border-bottom:1px solid #e3e3e3;overflow-wrap:anywhere}
table.ev th{background:#eee}table.ev th[scope=row]{min-width:9rem}.unit{font-weight:400;color:var(--muted)}
pre.raw{white-space:pre-wrap;overflow-wrap:anywhere;font-size:.75rem;max-height:22rem;overflow:auto;
background:var(--bg2);padding:.4rem}
.figs{display:flex;flex-wrap:wrap;gap:1rem;margin:.5rem 0}
figure{margin:.3rem 0;max-width:100%}
figure.plot-fig figcaption{font-size:.8rem;color:var(--muted);max-width:46rem}
svg.plot{max-width:100%;height:auto;border:1px solid #e3e3e3;background:#fff;display:block}
svg.plot *{stroke-linejoin:round;stroke-linecap:butt}
figure img{max-width:360px;border:1px solid var(--line);image-rendering:pixelated}
.box{border:2px solid;border-radius:6px;padding:.5rem .9rem;margin:1rem 0}
.box.flags{border-color:var(--fail)}.box.warn{border-color:var(--partial)}
.box h2{border:0;margin:.2rem 0}
.sr{position:absolute;width:1px;height:1px;overflow:hidden;clip-path:inset(50%);white-space:nowrap}
ul.problems pre{white-space:pre-wrap;margin:.2rem 0;font-size:.8rem;max-height:16rem;overflow:auto}
footer{color:var(--muted);font-size:.8rem;margin-top:2rem;border-top:1px solid var(--line)}
a{color:#0b4f9c}
.bar{display:flex;height:.9rem;min-width:8rem;border:1px solid var(--line)}
.bar span{display:block;height:100%}
.bar .b-pass{background:#0b6e2e}.bar .b-partial{background:#e69f00;background-image:repeating-linear-gradient(
45deg,transparent 0 3px,rgba(255,255,255,.55) 3px 5px)}.bar .b-fail{background:#a4161a;background-image:
repeating-linear-gradient(-45deg,transparent 0 2px,rgba(255,255,255,.45) 2px 4px)}.bar .b-error{background:#8e7cc3}
.who a{margin-right:.4rem;white-space:nowrap}
.controls{display:flex;flex-wrap:wrap;gap:.6rem 1.2rem;align-items:end;margin:.5rem 0;padding:.5rem;
background:var(--bg2);border-radius:6px}
.controls label{display:flex;flex-direction:column;font-size:.85rem;gap:.15rem}
.controls input,.controls select{font:inherit;padding:.15rem .3rem}
th button.sort{font:inherit;font-weight:600;background:none;border:0;padding:0;cursor:pointer;color:inherit;
text-align:inherit}
th button.sort::after{content:" ↕";color:var(--muted)}
th[aria-sort=ascending] button.sort::after{content:" ▲"}th[aria-sort=descending] button.sort::after{content:" ▼"}
.delta-up{color:var(--pass)}.delta-down{color:var(--fail)}
.scroll{overflow-x:auto}
@media (max-width:700px){.scores .score{flex:1 1 100%}body{padding:.6rem}
table.summary th:last-child,table.summary td:last-child{display:none}th,td{padding:.3rem .3rem}
table.summary th,table.summary td{overflow-wrap:anywhere}}
@media print{@page{size:auto;margin:12mm}body{font-size:10pt;max-width:none;padding:0}
th{background:none}table{page-break-inside:auto}tr,figure,.card h3,svg.plot{break-inside:avoid}
h2,h3{break-after:avoid}.controls,th button.sort::after,.replay-link{display:none}.scroll{overflow:visible}
table.subs{font-size:8.5pt}table.subs td,table.subs th{padding:.15rem .25rem;overflow-wrap:anywhere}
a{color:inherit;text-decoration:none}details>summary::marker{content:""}pre.raw{max-height:none}}
"""

#: the class view's sorting and filtering; the page is complete without it (controls hidden)
INDEX_JS = """
(function(){
  const table = document.getElementById('subs');
  if (!table) return;
  const body = table.tBodies[0];
  const rows = Array.from(body.rows);
  const controls = document.getElementById('controls');
  controls.hidden = false;
  const q = document.getElementById('f-text'), item = document.getElementById('f-item'),
        flag = document.getElementById('f-flag'), prob = document.getElementById('f-problem'),
        count = document.getElementById('f-count');
  function apply(){
    const text = q.value.trim().toLowerCase(); let shown = 0;
    for (const r of rows) {
      let ok = !text || r.dataset.submission.toLowerCase().includes(text);
      if (ok && item.value) ok = (' ' + r.dataset.failed + ' ').includes(' ' + item.value + ' ');
      if (ok && flag.value === 'any') ok = r.dataset.flags !== '';
      if (ok && flag.value === 'none') ok = r.dataset.flags === '';
      if (ok && prob.value === 'build') ok = r.dataset.build === 'failed';
      if (ok && prob.value === 'crash') ok = r.dataset.crashes !== '0';
      if (ok && prob.value === 'changed') ok = r.dataset.delta !== '' && r.dataset.delta !== '0';
      r.hidden = !ok; if (ok) shown++;
    }
    count.textContent = shown + ' of ' + rows.length + ' shown';
  }
  for (const el of [q, item, flag, prob]) el.addEventListener('input', apply);
  table.querySelectorAll('th[data-key]').forEach(function(th){
    const b = th.querySelector('button.sort');
    b.addEventListener('click', function(){
      const key = th.dataset.key, num = th.dataset.type === 'num';
      const dir = th.getAttribute('aria-sort') === 'descending' ? 'ascending' : 'descending';
      table.querySelectorAll('th[data-key]').forEach(h => h.removeAttribute('aria-sort'));
      th.setAttribute('aria-sort', dir);
      const sign = dir === 'ascending' ? 1 : -1;
      rows.sort(function(a, b){
        let x = a.dataset[key], y = b.dataset[key];
        if (num) { x = x === '' ? -Infinity : +x; y = y === '' ? -Infinity : +y; return sign * (x - y); }
        return sign * x.localeCompare(y);
      });
      rows.forEach(r => body.appendChild(r));
    });
  });
  apply();
})();
"""
