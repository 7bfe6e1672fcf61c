// Renders the mathematics that pymdownx.arithmatex (generic: true) leaves in the pages:
// \( ... \) in <span class="arithmatex"> and \[ ... \] in <div class="arithmatex">.
// Only those elements are rendered, so a dollar sign in a code block stays as it is.
// document$ is Material for MkDocs' page observable: it emits on the first load and again
// after every instant-navigation page change.
document$.subscribe(({ body }) => {
  body.querySelectorAll(".arithmatex").forEach((element) => {
    renderMathInElement(element, {
      delimiters: [
        { left: "\\(", right: "\\)", display: false },
        { left: "\\[", right: "\\]", display: true },
      ],
      throwOnError: false,
    })
  })
})
