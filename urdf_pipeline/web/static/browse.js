// urdf-pipeline's dataset browser (browse -o DIR): the rows of segments.json, searched and paged, the current page's
// rows and sparklines drawn, a segment opened in the viewer pane. Every string of segments.json comes from a manifest
// anyone may have edited: it goes into the page with textContent and setAttribute only, never as HTML.
"use strict";
(function () {
  const SVG = "http://www.w3.org/2000/svg";
  const WIDTH = 120;
  const HEIGHT = 28;
  const root = document.getElementById("browse");
  const defaultRows = Number(root.dataset.pageRows) || 50;
  let rowsPerPage = defaultRows;
  const search = document.getElementById("search");
  const body = document.querySelector("#segments tbody");
  const status = document.getElementById("status");
  const pageInfo = document.getElementById("page-info");
  const frame = document.getElementById("viewer");
  let segments = [];
  let names = [];
  let haystacks = [];
  let matches = [];
  let page = 0;
  let selected = "";

  function element(tag, text, className) {
    const made = document.createElement(tag);
    if (text !== undefined && text !== null) made.textContent = String(text);
    if (className) made.setAttribute("class", className);
    return made;
  }

  function state() {
    const fragment = new URLSearchParams(location.hash.slice(1));
    const rows = Math.floor(Number(fragment.get("n")));
    return {
      query: fragment.get("q") || "",
      page: Math.max(0, (Number(fragment.get("p")) || 1) - 1),
      rows: rows >= 1 && rows <= 500 ? rows : defaultRows,
    };
  }

  function keep() {
    const fragment = new URLSearchParams();
    if (search.value) fragment.set("q", search.value);
    if (page > 0) fragment.set("p", String(page + 1));
    if (rowsPerPage !== defaultRows) fragment.set("n", String(rowsPerPage));
    const wanted = fragment.toString();
    if (location.hash.slice(1) !== wanted) history.replaceState(null, "", wanted ? "#" + wanted : location.pathname + location.search);
  }

  function decode(text) {
    const raw = atob(text);
    const bytes = new Uint8Array(raw.length);
    for (let i = 0; i < raw.length; i++) bytes[i] = raw.charCodeAt(i);
    return bytes;
  }

  function sparkline(spark) {
    // One band per joint (its bucket's min to max, on its own scale), min codes then max codes per joint.
    const svg = document.createElementNS(SVG, "svg");
    svg.setAttribute("width", String(WIDTH));
    svg.setAttribute("height", String(HEIGHT));
    svg.setAttribute("viewBox", `0 0 ${WIDTH} ${HEIGHT}`);
    svg.setAttribute("class", "spark");
    const title = document.createElementNS(SVG, "title");
    const lines = [];
    let codes;
    try {
      codes = decode(spark.c);
    } catch (error) {
      return element("span", "no preview", "muted");
    }
    const buckets = spark.b;
    spark.j.forEach(function (joint, index) {
      const robot = names[spark.r[index]];
      lines.push(`${robot} ${names[joint]}${spark.l[index] ? " (against its limits)" : " (against the range it moved)"}`);
      const start = index * 2 * buckets;
      const top = [];
      const bottom = [];
      for (let b = 0; b < buckets; b++) {
        const low = codes[start + b];
        const high = codes[start + buckets + b];
        if (low > high) continue; // an empty bucket
        const x = (b + 0.5) * (WIDTH / buckets);
        top.push(`${x.toFixed(1)},${(HEIGHT - 1 - (high / 255) * (HEIGHT - 2)).toFixed(1)}`);
        bottom.unshift(`${x.toFixed(1)},${(HEIGHT - 1 - (low / 255) * (HEIGHT - 2)).toFixed(1)}`);
      }
      if (!top.length) return;
      const band = document.createElementNS(SVG, "polygon");
      band.setAttribute("points", top.concat(bottom).join(" "));
      band.setAttribute("class", `joint joint-${index % 6}`);
      svg.appendChild(band);
    });
    title.textContent = lines.join("\n");
    svg.insertBefore(title, svg.firstChild);
    return svg;
  }

  function open(segment) {
    if (typeof segment.href !== "string" || !segment.href.startsWith("viewer/index.html#")) return;
    selected = segment.id;
    document.getElementById("viewer-hint").hidden = true;
    frame.hidden = false;
    const fragment = segment.href.slice(segment.href.indexOf("#"));
    const loaded = frame.contentWindow && frame.getAttribute("src") && frame.contentWindow.location.pathname.endsWith("/viewer/index.html");
    if (loaded) {
      frame.contentWindow.location.hash = fragment; // the running viewer opens it: no second load of the wasm
    } else {
      frame.setAttribute("src", segment.href);
    }
    for (const row of body.rows) row.classList.toggle("selected", row.dataset.id === selected);
  }

  function diffText(d) {
    // compare: a commanded copy against its measured robot (names as data, shown with textContent)
    const bias = (d.bias || []).length ? `; calibration bias: ${d.bias.join(", ")}` : "";
    if (!d.beyond) return `${d.copy} vs ${d.measured}: within threshold over ${d.rows} rows${bias}`;
    return `${d.copy} vs ${d.measured}: ${d.beyond} of ${d.rows} rows beyond threshold: ${(d.joints || []).join(", ")}${bias}`;
  }

  function row(segment) {
    const tr = document.createElement("tr");
    tr.dataset.id = segment.id;
    if (segment.id === selected) tr.classList.add("selected");
    const idCell = element("td");
    if (segment.href) {
      const link = element("a", segment.id);
      link.setAttribute("href", segment.href);
      link.setAttribute("target", "_blank");
      link.setAttribute("rel", "noopener");
      link.addEventListener("click", function (event) {
        if (event.button === 0 && !event.ctrlKey && !event.metaKey && !event.shiftKey) {
          event.preventDefault();
          open(segment);
        }
      });
      idCell.appendChild(link);
    } else {
      idCell.appendChild(element("span", segment.id));
    }
    if (segment.missing) idCell.appendChild(element("div", segment.missing, "bad small"));
    tr.appendChild(idCell);
    tr.appendChild(element("td", segment.frames, "number"));
    tr.appendChild(element("td", typeof segment.seconds === "number" ? segment.seconds.toFixed(2) : "", "number"));
    tr.appendChild(element("td", segment.time || "", "small"));
    tr.appendChild(element("td", (segment.robots || []).join(", ")));
    const preview = element("td");
    if (segment.spark) preview.appendChild(sparkline(segment.spark));
    tr.appendChild(preview);
    const notes = element("td", null, "small");
    for (const note of segment.notes || []) notes.appendChild(element("div", note));
    if (segment.left) notes.appendChild(element("div", `and ${segment.left} more`, "muted"));
    for (const d of segment.diff || []) notes.appendChild(element("div", diffText(d), d.beyond || (d.bias || []).length ? "bad" : "muted"));
    tr.appendChild(notes);
    return tr;
  }

  function render() {
    const pages = Math.max(1, Math.ceil(matches.length / rowsPerPage));
    page = Math.min(page, pages - 1);
    const shown = matches.slice(page * rowsPerPage, (page + 1) * rowsPerPage);
    body.replaceChildren(...shown.map(function (index) { return row(segments[index]); }));
    pageInfo.textContent = `page ${page + 1} of ${pages} (${matches.length} of ${segments.length} segments)`;
    document.getElementById("previous").disabled = page === 0;
    document.getElementById("next").disabled = page >= pages - 1;
    status.textContent = matches.length ? "" : "No segment matches.";
    keep();
  }

  function filter() {
    const words = search.value.toLowerCase().split(/\s+/).filter(Boolean);
    matches = [];
    for (let i = 0; i < haystacks.length; i++) {
      if (words.every(function (word) { return haystacks[i].includes(word); })) matches.push(i);
    }
  }

  let typing = 0;
  search.addEventListener("input", function () {
    clearTimeout(typing);
    typing = setTimeout(function () { page = 0; filter(); render(); }, 120);
  });
  document.getElementById("previous").addEventListener("click", function () { page -= 1; render(); });
  document.getElementById("next").addEventListener("click", function () { page += 1; render(); });
  window.addEventListener("hashchange", function () {
    const wanted = state();
    if (wanted.query !== search.value) { search.value = wanted.query; filter(); }
    page = wanted.page;
    rowsPerPage = wanted.rows;
    render();
  });

  fetch(root.dataset.src)
    .then(function (answer) {
      if (!answer.ok) throw new Error(`${answer.status} ${answer.statusText}`);
      return answer.json();
    })
    .then(function (data) {
      segments = Array.isArray(data.segments) ? data.segments : [];
      names = Array.isArray(data.names) ? data.names : [];
      haystacks = segments.map(function (s) {
        return [s.id, (s.robots || []).join(" "), (s.notes || []).join(" "), (s.diff || []).map(diffText).join(" "), s.missing || ""].join("\n").toLowerCase();
      });
      const wanted = state();
      search.value = wanted.query;
      page = wanted.page;
      rowsPerPage = wanted.rows;
      filter();
      render();
      root.dataset.state = "ready";
    })
    .catch(function (error) {
      status.textContent = `Cannot read ${root.dataset.src}: ${error}`;
      root.dataset.state = "failed";
    });
})();
