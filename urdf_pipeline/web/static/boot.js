// urdf-pipeline's start of Rerun's web viewer (re_viewer.js and re_viewer_bg.wasm of the pinned release, beside
// this file). It replaces the stock index.html, which requests web fonts, analytics and a version check.
//
// The recordings to open come from the page's address, as `url` parameters of its query or its fragment
// (`index.html#url=../recordings/a.rrd&url=../recordings/a.rbl`), written RELATIVE to this page so the site works under
// any path prefix on any static host. Each is made absolute here (the viewer loads an absolute URL, not a relative
// one) and must stay on this page's own origin: anything else is refused and named on the page. A later change of the
// fragment opens its new recordings in the running viewer (no second load of the wasm).
//
// `asset=MODEL&into=RECORDING_ID` (browse, split layout): the model asset's chunks are added to the recording
// RECORDING_ID (the segment's layer), as a Rerun catalog applies a dataset asset to each segment: see `joinAsset`.
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

  // The `url` (or `asset`) parameters of the query and the fragment, resolved against this page; [accepted, refused].
  function recordings(name = "url") {
    const accepted = [];
    const refused = [];
    for (const part of [location.search, location.hash]) {
      for (const value of new URLSearchParams(part.slice(1)).getAll(name)) {
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
    openAssets();
  }

  // A split layout's model is one recording (id `urdf_model`) of static chunks; each segment's layer is a recording of
  // its own id. The viewer merges only chunks of one recording id, and a static site has no catalog to apply an asset
  // to a segment, nor room for a copy of the model per segment. So the model is fetched once and, per segment, given
  // to the viewer under the segment's recording id: each message of the .rrd stream gets one protobuf field appended
  // (its store id's recording_id), which the viewer's own decoder merges over the message's field, as it reads a
  // message written with that id. Nothing of the model is decoded here: only the stream's frames (kind, length) are
  // walked. The stream's end and footer (an index of byte offsets) are left out: the bytes moved.
  const FRAME_END = 0n;
  const TAILS = [
    [1n, [2, 2]], // SetStoreInfo { info (2): StoreInfo { store_id (2): StoreId { recording_id (2) } } }
    [2n, [1]], // ArrowMsg { store_id (1): StoreId { recording_id (2) } }
    [3n, null], // BlueprintActivationCommand: none in a model; dropped
  ];
  const assetBytes = new Map(); // asset URL -> Promise of its bytes (fetched once per page)
  const joined = new Set(); // asset URL + recording id given to the viewer already
  let channels = 0;

  // `bytes` as a length-delimited protobuf field `number`.
  function field(number, bytes) {
    const head = [(number << 3) | 2];
    for (let n = bytes.length; ; n = Math.floor(n / 128)) {
      head.push(n >= 128 ? (n % 128) | 128 : n);
      if (n < 128) break;
    }
    const out = new Uint8Array(head.length + bytes.length);
    out.set(head, 0);
    out.set(bytes, head.length);
    return out;
  }

  // The .rrd stream `bytes` with every message's store id set to `recordingId` (kind and application id kept).
  function joinAsset(bytes, recordingId) {
    if (bytes.length < 12 || String.fromCharCode(...bytes.subarray(0, 4)) !== "RRF2") {
      throw new Error("not an .rrd stream of this Rerun release");
    }
    const storeId = field(2, new TextEncoder().encode(recordingId));
    const tails = new Map(TAILS.map(([kind, path]) => [kind, path && path.reduceRight((inner, number) => field(number, inner), storeId)]));
    const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
    const frames = [bytes.subarray(0, 12)]; // the stream header: magic, version, options
    let offset = 12;
    while (offset + 16 <= bytes.length) {
      const kind = view.getBigUint64(offset, true);
      const length = Number(view.getBigUint64(offset + 8, true));
      if (kind === FRAME_END) break;
      const tail = tails.get(kind);
      if (tail === undefined || offset + 16 + length > bytes.length) throw new Error("an .rrd frame this page does not know");
      if (tail) {
        const frame = new Uint8Array(16 + length + tail.length);
        frame.set(bytes.subarray(offset, offset + 16 + length), 0);
        new DataView(frame.buffer).setBigUint64(8, BigInt(length + tail.length), true);
        frame.set(tail, 16 + length);
        frames.push(frame);
      }
      offset += 16 + length;
    }
    const out = new Uint8Array(frames.reduce((sum, frame) => sum + frame.length, 0));
    frames.reduce((at, frame) => (out.set(frame, at), at + frame.length), 0);
    return out;
  }

  function openAssets() {
    const [assets, refused] = recordings("asset");
    refuse(refused);
    const into = new URLSearchParams(location.hash.slice(1)).get("into");
    if (!into) return;
    for (const url of assets) {
      const key = JSON.stringify([url, into]);
      if (joined.has(key)) continue;
      joined.add(key);
      if (!assetBytes.has(url)) {
        assetBytes.set(url, siteFetch(url).then((response) => {
          if (!response.ok) throw new Error(response.status + " " + response.statusText);
          return response.arrayBuffer();
        }));
      }
      assetBytes.get(url).then((buffer) => {
        const channel = "asset-" + ++channels;
        handle.open_channel(channel, url.slice(url.lastIndexOf("/") + 1));
        handle.send_rrd_to_channel(channel, joinAsset(new Uint8Array(buffer), into));
        handle.close_channel(channel);
      }).catch((error) => {
        console.error("urdf-pipeline viewer: the model " + url + " was not added to " + JSON.stringify(into.slice(0, 200)) + ": " + error);
        say("The robot's model could not be added to this segment: " + error, "failed");
      });
    }
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
    openAssets();
    window.addEventListener("hashchange", openNew);
  }

  start();
})();
