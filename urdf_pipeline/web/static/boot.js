// urdf-pipeline's start of Rerun's web viewer (re_viewer.js and re_viewer_bg.wasm of the pinned release, beside
// this file). It replaces the stock index.html, which requests web fonts, analytics and a version check.
//
// The recordings to open come from the page's address, as `url` parameters of its query or its fragment
// (`index.html#url=../recordings/a.rrd&url=../recordings/a.rbl`), written RELATIVE to this page so the site works under
// any path prefix on any static host. Each is made absolute here (the viewer loads an absolute URL, not a relative
// one) and must stay on this page's own origin: anything else is refused and named on the page. A later change of the
// fragment opens its new recordings in the running viewer (no second load of the wasm).
"use strict";

(function () {
  const script = document.currentScript;
  const wasmUrl = new URL("re_viewer_bg.wasm", script.src);
  const status = document.getElementById("status");
  const canvas = document.getElementById("viewer-canvas");
  const opened = new Set();
  let handle = null;

  // The viewer sends usage analytics (tel.rerun.io) and has no option to stop that on the web, and the page's policy
  // (Content-Security-Policy connect-src 'self') would refuse it with a console error. So a fetch of another origin
  // is answered here, empty, and never leaves the browser (named once on the console, at info level); this site's
  // own files are fetched as usual.
  const siteFetch = window.fetch.bind(window);
  const keptHere = new Set();
  window.fetch = function (resource, init) {
    const target = new URL(resource instanceof Request ? resource.url : String(resource), location.href);
    if (target.origin !== location.origin && target.protocol !== "blob:" && target.protocol !== "data:") {
      if (!keptHere.has(target.origin + target.pathname)) {
        keptHere.add(target.origin + target.pathname);
        console.info("urdf-pipeline viewer: not sent (this page requests nothing outside its site): " + target.origin + target.pathname);
      }
      return Promise.resolve(new Response(null, { status: 204, statusText: "not sent" }));
    }
    return siteFetch(resource, init);
  };
  window.urdfPipelineNotSent = keptHere;

  // The viewer keeps its state (layout, blueprints per application id) in the browser and has no option to stop that
  // on the web: cleared before it starts, so each visit shows the recordings' own blueprints, not an older page's.
  function forgetViewerState() {
    try {
      for (const key of ["app", "egui_memory_ron"]) {
        window.localStorage.removeItem(key);
      }
    } catch (error) {
      // storage disabled: nothing was kept either
    }
  }

  function say(text, state) {
    status.textContent = text;
    status.hidden = !text;
    document.body.dataset.state = state;
  }

  // The `url` parameters of the query and the fragment, resolved against this page; [accepted, refused].
  function recordings() {
    const accepted = [];
    const refused = [];
    for (const part of [location.search, location.hash]) {
      for (const value of new URLSearchParams(part.slice(1)).getAll("url")) {
        let url = null;
        try {
          url = new URL(value, location.href);
        } catch (error) {
          refused.push(value);
          continue;
        }
        const local = url.origin === location.origin && (url.protocol === "http:" || url.protocol === "https:");
        (local ? accepted : refused).push(local ? url.href : value);
      }
    }
    return [accepted, refused];
  }

  function refuse(refused) {
    if (refused.length) {
      const names = refused.map((value) => JSON.stringify(value.slice(0, 200))).join(", ");
      console.warn("urdf-pipeline viewer: not opened (not a file of this site): " + names);
      say("Not opened (not a file of this site): " + names, "refused");
    }
  }

  function watchForPanic() {
    if (handle.has_panicked()) {
      const message = String(handle.panic_message());
      console.error("the Rerun viewer crashed: " + message);
      canvas.hidden = true;
      say("The Rerun viewer crashed: " + message + " (reload the page to try again)", "crashed");
      return;
    }
    setTimeout(watchForPanic, 1000);
  }

  function openNew() {
    const [accepted, refused] = recordings();
    for (const url of accepted) {
      if (!opened.has(url)) {
        opened.add(url);
        handle.add_receiver(url);
      }
    }
    say("", "started");
    refuse(refused);
  }

  async function start() {
    if (typeof wasm_bindgen !== "function") {
      say("The viewer's script re_viewer.js did not load.", "failed");
      return;
    }
    const [accepted, refused] = recordings();
    say("Loading the Rerun viewer (about 43 MB)…", "loading");
    try {
      await wasm_bindgen({ module_or_path: wasmUrl });
      forgetViewerState();
      accepted.forEach((url) => opened.add(url));
      handle = new wasm_bindgen.WebHandle({
        url: accepted,
        hide_welcome_screen: true,
        enable_history: false,
        check_for_updates_on_startup: false,
        notebook: false,
      });
      watchForPanic();
      await handle.start(canvas);
    } catch (error) {
      console.error("the Rerun viewer did not start: " + error);
      canvas.hidden = true;
      say("The Rerun viewer did not start: " + error, "failed");
      return;
    }
    canvas.hidden = false;
    say(accepted.length || refused.length ? "" : "No recording to show: open this page from a link of the site, which names them.", "started");
    refuse(refused);
    window.addEventListener("hashchange", openNew);
  }

  start();
})();
