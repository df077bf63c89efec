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
  r.scroll_width = document.documentElement.scrollWidth;
  r.inner_width = window.innerWidth;
  const pre = document.createElement('pre');
  pre.id = 'bench-check';
  pre.textContent = JSON.stringify(r);
  document.body.appendChild(pre);
});
