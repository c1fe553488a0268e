// The web page's loader: fetches the demo's WebAssembly (web/src, built by
// `cargo run --release -p web`), passes key, touch and pointer events, the
// register lab's edits and the URL in, and puts
// the pixels it draws on the canvases. All logic is in the module; this
// file only moves bytes. No bindings generator: the module exports plain
// functions and buffers in its memory (docs/web.md lists them).
(function () {
  "use strict";
  const $ = (id) => document.getElementById(id);
  const hook = { ready: false };
  window.modexPage = hook;
  // Text changes the document only when it changes: each change costs the
  // browser a style pass.
  const shownText = new Map();
  function setText(id, value) {
    if (shownText.get(id) !== value) {
      shownText.set(id, value);
      $(id).textContent = value;
    }
  }
  const say = (text) => setText("message", text);

  if (typeof WebAssembly !== "object" || typeof WebAssembly.instantiate !== "function") {
    say("This page needs WebAssembly, which this browser lacks or has switched off.");
    return;
  }
  // The module is built with WebAssembly's 128-bit SIMD (.cargo/config.toml),
  // which browsers since 2021 (Safari since 2023) have. The smallest module
  // that uses it: one function, i32.const 0, i8x16.splat.
  const simdProbe = new Uint8Array([
    0, 97, 115, 109, 1, 0, 0, 0, 1, 5, 1, 96, 0, 1, 123, 3, 2, 1, 0, 10, 8, 1, 6, 0, 65, 0, 253, 15, 11,
  ]);
  if (!WebAssembly.validate(simdProbe)) {
    say("This page needs WebAssembly SIMD (Chrome or Edge 91, Firefox 89, Safari 16.4 or later), " +
        "which this browser lacks.");
    return;
  }

  // The module comes deflated (zlib's format: a seventh of its size), in
  // base64 inside the single-file page or as modex.wasm.deflate beside it
  // (see web/src/build.rs); the browser inflates it.
  async function loadModule() {
    if (typeof DecompressionStream !== "function") {
      throw new Error("this browser has no DecompressionStream to inflate it");
    }
    let deflated;
    const inline = $("modex-wasm");
    if (inline) {
      const text = atob(inline.textContent.trim());
      const bytes = new Uint8Array(text.length);
      for (let i = 0; i < text.length; i++) bytes[i] = text.charCodeAt(i);
      deflated = new Blob([bytes]).stream();
    } else {
      const response = await fetch("modex.wasm.deflate");
      if (!response.ok) throw new Error("modex.wasm.deflate: HTTP " + response.status);
      deflated = response.body;
    }
    const inflated = deflated.pipeThrough(new DecompressionStream("deflate"));
    return WebAssembly.instantiate(await new Response(inflated).arrayBuffer(), {});
  }

  loadModule().then(
    (result) => start(result.instance.exports),
    (error) => say("The page could not load its WebAssembly: " + error)
  );

  function start(w) {
    const encoder = new TextEncoder();
    const decoder = new TextDecoder();
    // Views are made afresh each time: memory may have grown since.
    const bytes = (pointer, length) => new Uint8Array(w.memory.buffer, pointer >>> 0, length);
    function put(text) {
      const encoded = encoder.encode(text);
      bytes(w.input_buffer(encoded.length), encoded.length).set(encoded);
      return encoded.length;
    }
    const text = (length) => decoder.decode(bytes(w.output_ptr(), length));
    function base64(view) {
      let binary = "";
      for (let i = 0; i < view.length; i += 0x8000) {
        binary += String.fromCharCode.apply(null, view.subarray(i, i + 0x8000));
      }
      return btoa(binary);
    }

    const screen = $("screen");
    const inspector = $("inspector");
    const ops = $("ops");
    // Each canvas keeps its context and an ImageData over the module's
    // pixels, made again only when they move or memory grows: a frame
    // makes no garbage here. A tracked canvas (0: the picture, 1: the
    // inspector) takes only the rows the module says changed since.
    const painters = new Map();
    function paint(canvas, pointer, width, height, tracked) {
      let painter = painters.get(canvas);
      if (!painter) {
        painter = { context: canvas.getContext("2d"), image: null, pointer: 0 };
        painters.set(canvas, painter);
      }
      const image = painter.image;
      if (!image || image.data.buffer !== w.memory.buffer || painter.pointer !== pointer ||
          image.width !== width || image.height !== height) {
        const pixels = new Uint8ClampedArray(w.memory.buffer, pointer >>> 0, width * height * 4);
        painter.image = new ImageData(pixels, width, height);
        painter.pointer = pointer;
      }
      if (tracked === undefined) {
        painter.context.putImageData(painter.image, 0, 0);
        return;
      }
      const runs = w.changed_rows(tracked);
      for (let i = 0; i < runs; i++) {
        painter.context.putImageData(painter.image, 0, 0, 0, w.run_top(i), width, w.run_rows(i));
      }
    }
    // Visibility, like text, changes only when it changes.
    function setHidden(element, hidden) {
      if (element.hidden !== hidden) element.hidden = hidden;
    }

    let textsVersion = -1;
    let labOpen = false;
    let shownFrames = -1;
    function draw() {
      paint(screen, w.screen_ptr(), 320, 240, 0);
      const panel = w.panel_ptr();
      setHidden(inspector, !panel);
      if (panel) paint(inspector, panel, w.panel_width(), w.panel_height(), 1);
      const slow = w.ops_ptr();
      setHidden(ops, !slow);
      if (slow) paint(ops, slow, w.ops_width(), w.ops_height());
      // The texts cross from the module only when they have changed.
      const version = w.texts_version();
      if (version !== textsVersion) {
        textsVersion = version;
        setText("last-op", text(w.last_op()));
        say(text(w.message()));
      }
      setText("play", w.paused() ? "Play" : "Pause");
      const frames = w.frames();
      if (frames !== shownFrames) {
        shownFrames = frames;
        setText("frame-count", "frame " + frames);
      }
      if (labOpen) showLab();
    }

    let stopped = false;
    // A trap in the module (a bug) stops the page with a message, not silently.
    function guarded(action) {
      return function () {
        if (stopped) return undefined;
        try {
          return action.apply(this, arguments);
        } catch (error) {
          stopped = true;
          say("The page stopped: " + error);
          throw error;
        }
      };
    }

    // Keys: only while the picture has the focus, so the rest of the page
    // scrolls and tabs as usual. The module says which keys it takes.
    screen.addEventListener("keydown", guarded((event) => {
      const taken = w.key_down(put(event.code));
      if (taken && !event.ctrlKey && !event.metaKey) event.preventDefault();
    }));
    screen.addEventListener("keyup", guarded((event) => {
      if (w.key_up(put(event.code))) event.preventDefault();
    }));
    // A key held when the focus leaves gets no key-up: release it now.
    screen.addEventListener("blur", guarded(() => w.release_keys()));
    window.addEventListener("blur", guarded(() => w.release_keys()));

    screen.addEventListener("mousemove", guarded((event) => {
      const box = screen.getBoundingClientRect();
      const x = Math.floor(((event.clientX - box.left) * 320) / box.width);
      const y = Math.floor(((event.clientY - box.top) * 240) / box.height);
      if (x >= 0 && y >= 0) setText("hover", text(w.hover(x, y)));
    }));

    $("play").addEventListener("click", guarded(() => {
      if (w.paused()) w.play();
      else w.pause();
      draw();
      tickWhilePlaying();
    }));
    $("step-frame").addEventListener("click", guarded(() => {
      w.step_frames(1);
      draw();
    }));
    $("step-op").addEventListener("click", guarded(() => {
      w.step_ops(1);
      draw();
    }));
    function download(blob, name) {
      const link = document.createElement("a");
      link.href = URL.createObjectURL(blob);
      link.download = name;
      link.click();
      setTimeout(() => URL.revokeObjectURL(link.href), 10000);
    }
    $("record-gif").addEventListener("click", guarded(() => {
      const length = w.gif();
      draw();
      if (!length) return;
      const blob = new Blob([bytes(w.output_ptr(), length).slice()], { type: "image/gif" });
      download(blob, "modex-cube-" + w.frames() + "-frames.gif");
      say("Recorded " + length + " bytes of GIF.");
      textsVersion = -1; // the module's message replaces it at the next draw, as before
    }));

    // The on-screen keys: each a tap of its key, through the same key
    // events (key_down, key_up) the keyboard gives.
    function tapKey(code) {
      w.key_down(put(code));
      w.key_up(put(code));
    }
    function connectKeypad() {
      for (const button of document.querySelectorAll("#keypad button")) {
        button.addEventListener("click", guarded(() => {
          tapKey(button.dataset.code);
          draw();
        }));
      }
    }

    // Touch, pen and mouse on the picture: the module turns one pointer
    // dragged, two pinched and the wheel into the keys that turn and move.
    function connectPointer() {
      screen.addEventListener("pointerdown", guarded((event) => {
        screen.focus();
        screen.setPointerCapture(event.pointerId);
        w.pointer_down(event.pointerId, event.clientX, event.clientY);
      }));
      screen.addEventListener("pointermove", guarded((event) => {
        w.pointer_move(event.pointerId, event.clientX, event.clientY);
      }));
      const lift = guarded((event) => w.pointer_up(event.pointerId));
      screen.addEventListener("pointerup", lift);
      screen.addEventListener("pointercancel", lift);
      screen.addEventListener("wheel", guarded((event) => {
        event.preventDefault();
        w.zoom(event.deltaY * [1, 16, 400][event.deltaMode]);
      }), { passive: false });
    }

    // The register lab: its table comes from the module (lab_html) when
    // first opened; while open, each field shows the value the VGA holds.
    const lab = $("lab-registers");
    let labWritten = null;
    function writeLab(input) {
      input.dataset.written = input.value;
      // Written, the field shows what the VGA took; refused, it keeps the
      // typing, and the message says why.
      if (w.lab_edit(put(input.dataset.key + "=" + input.value))) labWritten = input;
      draw();
      labWritten = null;
    }
    function showLab() {
      const inputs = lab.getElementsByTagName("input");
      const lines = text(w.lab_table()).split("\n");
      for (let i = 0; i < inputs.length; i++) {
        const [, , , , value, mark] = lines[i].split("\t");
        const input = inputs[i];
        const typing = document.activeElement === input && labWritten !== input;
        if (input.value !== value && !typing) input.value = value;
        const reason = input.parentElement.nextElementSibling;
        if (reason.textContent !== mark) {
          reason.textContent = mark;
          reason.parentElement.classList.toggle("harm", mark !== "");
        }
      }
      const params = new URLSearchParams(location.search);
      const edits = text(w.lab_url_value());
      if (edits) params.set("lab", edits);
      else params.delete("lab");
      $("lab-url").href = "?" + params.toString();
    }
    function connectLab() {
      $("lab").addEventListener("toggle", guarded(() => {
        labOpen = $("lab").open;
        if (labOpen && !lab.firstChild) lab.innerHTML = text(w.lab_html());
        draw();
      }));
      // Enter writes the value even if it is the one shown (to hold it);
      // leaving a changed field writes it too, once.
      lab.addEventListener("keydown", guarded((event) => {
        if (event.key === "Enter" && event.target.dataset.key) writeLab(event.target);
      }));
      lab.addEventListener("change", guarded((event) => {
        if (event.target.value !== event.target.dataset.written) writeLab(event.target);
      }));
      lab.addEventListener("focusin", (event) => delete event.target.dataset.written);
      $("lab-restore").addEventListener("click", guarded(() => {
        w.lab_restore();
        draw();
      }));
      $("lab-export").addEventListener("click", guarded(() => {
        download(new Blob([text(w.lab_export())], { type: "text/csv" }), "modex-lab-mode.csv");
      }));
    }
    connectKeypad();
    connectPointer();
    connectLab();

    // Frames on the display's refresh while the page plays; the module
    // runs as many frames of the software VGA's 59.7 Hz as are due, three
    // at most. A paused page asks for no refreshes, so the browser has
    // nothing to do for it at each one; playing asks again.
    let ticking = false;
    function tick(now) {
      if (stopped || w.paused()) {
        ticking = false;
        return;
      }
      if (guarded(w.frame)(now) > 0) draw();
      requestAnimationFrame(tick);
    }
    function tickWhilePlaying() {
      if (!ticking && !stopped && !w.paused()) {
        ticking = true;
        requestAnimationFrame(tick);
      }
    }

    // The test hook (tests/web_page.rs drives the page through it).
    function picture(pointer, width, height) {
      return pointer ? { width: width, height: height, rgba: base64(bytes(pointer, width * height * 4)) } : null;
    }
    Object.assign(hook, {
      pause: guarded(() => { w.pause(); draw(); }),
      play: guarded(() => { w.play(); draw(); tickWhilePlaying(); }),
      stepFrames: guarded((n) => { const ran = w.step_frames(n); draw(); return ran; }),
      stepOps: guarded((n) => { const done = w.step_ops(n); draw(); return done; }),
      frames: () => w.frames(),
      paused: () => w.paused() === 1,
      screenRgba: () => base64(bytes(w.screen_ptr(), 320 * 240 * 4)),
      inspectorRgba: () => picture(w.panel_ptr(), w.panel_width(), w.panel_height()),
      opsRgba: () => picture(w.ops_ptr(), w.ops_width(), w.ops_height()),
      setInspector: guarded((shown) => { w.set_inspector(shown ? 1 : 0); draw(); }),
      hover: (x, y) => text(w.hover(x, y)),
      lastOp: () => text(w.last_op()),
      message: () => text(w.message()),
      gif: guarded(() => { const length = w.gif(); return base64(bytes(w.output_ptr(), length)); }),
      labExport: () => text(w.lab_export()),
      labUrlValue: () => text(w.lab_url_value()),
    });

    guarded(() => w.init(put(location.search)))();
    if (stopped) return;
    draw();
    hook.ready = true;
    screen.focus();
    tickWhilePlaying();
  }
})();
