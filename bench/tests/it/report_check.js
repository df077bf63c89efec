// Injected into a copy of a report page by bench/tests/it/report_browser.rs: once the page and
// its PNGs have loaded, writes what the browser rendered into <pre id="bench-check"> as JSON.
window.addEventListener('load', async () => {
  const r = {};
  const text = document.body.innerText;
  r.markup_in_text = (text.match(/<\/?[a-zA-Z][^>]{0,20}>?|&(lt|gt|amp|quot|#\d+);/g) || []).slice(0, 5);
  r.svgs = Array.from(document.querySelectorAll('figure svg')).map(s => {
    const b = s.getBoundingClientRect();
    return [Math.round(b.width), Math.round(b.height)];
  });
  r.figures = document.querySelectorAll('figure').length;
  const srcs = Array.from(document.images).map(i => i.src)
    .concat(Array.from(document.querySelectorAll('a[href$=".png"]')).map(a => a.href));
  r.images = await Promise.all(srcs.map(src => new Promise(ok => {
    const img = new Image();
    img.onload = () => ok([src.split('/').pop(), img.naturalWidth, img.naturalHeight]);
    img.onerror = () => ok([src.split('/').pop(), 0, 0]);
    img.src = src;
  })));
  // Every text of every figure, measured as drawn (turned labels included): its box, and
  // each pair of texts whose boxes overlap by more than a hair (0.5 px each way).
  r.figure_texts = Array.from(document.querySelectorAll('figure')).map(f => {
    const texts = Array.from(f.querySelectorAll('svg text'))
      .filter(t => t.textContent.trim() !== '')
      .map(t => {
        const b = t.getBoundingClientRect();
        return [t.textContent.trim(), b.left, b.top, b.width, b.height];
      });
    const overlaps = [];
    for (let i = 0; i < texts.length; i++) {
      for (let j = i + 1; j < texts.length; j++) {
        const [, ax, ay, aw, ah] = texts[i];
        const [, bx, by, bw, bh] = texts[j];
        const ox = Math.min(ax + aw, bx + bw) - Math.max(ax, bx);
        const oy = Math.min(ay + ah, by + bh) - Math.max(ay, by);
        if (ox > 0.5 && oy > 0.5) overlaps.push([texts[i], texts[j]]);
      }
    }
    const fills = {};
    f.querySelectorAll('svg rect').forEach(rc => {
      const c = (rc.getAttribute('fill') || '').toUpperCase();
      fills[c] = (fills[c] || 0) + 1;
    });
    return {id: f.id, texts, overlaps, rect_fills: fills};
  });
  r.scroll_width = document.documentElement.scrollWidth;
  r.inner_width = window.innerWidth;
  const pre = document.createElement('pre');
  pre.id = 'bench-check';
  pre.textContent = JSON.stringify(r);
  document.body.appendChild(pre);
});
