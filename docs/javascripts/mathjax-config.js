// MathJax 3 for pymdownx.arithmatex (generic mode), as mkdocs-material documents it; MathJax itself is served from
// this site (javascripts/mathjax/, its CHTML fonts beside it), so the pages ask nothing of another host.
window.MathJax = {
  tex: {
    inline: [["\\(", "\\)"]],
    display: [["\\[", "\\]"]],
    processEscapes: true,
    processEnvironments: true
  },
  options: {
    ignoreHtmlClass: ".*|",
    processHtmlClass: "arithmatex"
  }
};

// A page Material swaps in is typeset again; the first page is typeset by MathJax's own start-up (before that, the
// functions below do not exist yet).
document$.subscribe(() => {
  if (typeof MathJax.typesetPromise !== "function") {
    return;
  }
  MathJax.startup.output.clearCache();
  MathJax.typesetClear();
  MathJax.texReset();
  MathJax.typesetPromise();
});
