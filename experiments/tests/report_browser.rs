//! The report in a browser (issue 35): headless Chromium (Debian's `chromium`, installed by
//! `scripts/install-deps`) loads the report of a quick sweep: the index page and every sweep
//! page. On each, no script error and no `console.error`, every image decodes (`complete` and
//! `naturalWidth > 0` at `load`; lazy images are made eager first, so `load` waits for them), and
//! no image the report names is shown as missing or not embedded (a quick sweep writes all of
//! them), and every section link (`#anchor`) names a heading of the page; the self-contained
//! `report.html` is loaded too. A screenshot of the
//! index's first screen is saved as `target/tmp/report-first-screen.png`.
//!
//! No webdriver: a copy of each page gets a small script at the top of its `<head>` that records
//! script errors (`error` events, images' too, in the capture phase) and `console.error` calls,
//! and after `load` writes the image and error counts as JSON into the DOM, which Chromium prints
//! with `--dump-dom` (virtual time lets the page settle). Every Chromium run has a hard timeout
//! ([`BROWSER_TIMEOUT`]) and a fresh profile folder; it is started with the flags that keep it off
//! the network (a closed network otherwise stalls it on look-ups).
//!
//! Without Chromium the test fails and says how to install it, unless
//! `FORESTLOD_ALLOW_NO_BROWSER=1` is set (as `FORESTLOD_ALLOW_NO_GPU=1` for the GPU tests; CI
//! never sets it). `FORESTLOD_CHROMIUM` names another binary.
//!
//! The quick sweep is `lod_settings` on the reference backend (a few seconds in a debug test
//! build; the wall time is printed).

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use forestlod_experiments::report::write_report;
use forestlod_experiments::sweep::{SweepArgs, run};

/// Longest a Chromium run may take before it is killed and the test fails: a page of the quick
/// report loads in about a second; 60 s leaves room for a loaded 2-core CI machine.
const BROWSER_TIMEOUT: Duration = Duration::from_secs(60);

/// The id of the element the injected script writes its result into.
const RESULT_ID: &str = "forestlod-browser-test";

/// Injected at the top of `<head>` of a test copy of a page (module docs).
const PROBE: &str = r##"<script>
(function(){
  var errors=[];
  window.addEventListener('error',function(e){
    var t=e.target;
    errors.push(t&&t.tagName?('resource error: '+t.tagName+' '+(t.getAttribute('src')||t.getAttribute('href'))):('script error: '+e.message));
  },true);
  window.addEventListener('unhandledrejection',function(e){errors.push('unhandled rejection: '+e.reason);});
  var ce=console.error;
  console.error=function(){errors.push('console.error: '+Array.prototype.join.call(arguments,' '));return ce.apply(console,arguments);};
  window.addEventListener('load',function(){
    var imgs=Array.prototype.slice.call(document.images);
    var bad=imgs.filter(function(i){return !(i.complete&&i.naturalWidth>0);})
      .map(function(i){return 'not decoded (naturalWidth '+i.naturalWidth+'): '+i.getAttribute('src');});
    Array.prototype.forEach.call(document.querySelectorAll('.missing'),function(m){bad.push('not shown: '+m.textContent);});
    Array.prototype.forEach.call(document.querySelectorAll('a[href^="#"]'),function(a){
      var id=decodeURIComponent(a.getAttribute('href').slice(1));
      if(!document.getElementById(id)){errors.push('section link to nothing: #'+id);}
    });
    var r=document.createElement('pre');
    r.id='RESULT_ID';
    r.textContent=JSON.stringify({images:imgs.length,broken:bad,errors:errors});
    document.body.appendChild(r);
  });
})();
</script>"##;

/// The Chromium binary: `FORESTLOD_CHROMIUM`, else the first of Debian's and others' names on
/// `PATH`.
fn chromium() -> Option<PathBuf> {
    if let Some(p) = std::env::var_os("FORESTLOD_CHROMIUM") {
        return Some(PathBuf::from(p));
    }
    let path = std::env::var_os("PATH")?;
    ["chromium", "chromium-browser", "google-chrome", "chrome"]
        .iter()
        .flat_map(|name| std::env::split_paths(&path).map(move |d| d.join(name)))
        .find(|p| p.is_file())
}

/// Runs Chromium headless with `args` after the network-free flags and a fresh profile under
/// `work`; returns its stdout, or an error naming what went wrong (a timeout kills it).
fn browse(browser: &Path, work: &Path, args: &[String]) -> Result<String, String> {
    let profile = work.join(format!(
        "profile-{}",
        std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap()
            .as_nanos()
    ));
    let mut child = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-quic",
            "--no-first-run",
            "--disable-background-networking",
            "--disable-component-update",
            "--disable-sync",
            "--disable-extensions",
            "--disable-dev-shm-usage",
            "--hide-scrollbars",
        ])
        .arg(format!("--user-data-dir={}", profile.display()))
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot start {}: {e}", browser.display()))?;
    // Drain both pipes on threads so a chatty browser never blocks on a full pipe.
    let mut stdout = child.stdout.take().unwrap();
    let mut stderr = child.stderr.take().unwrap();
    let out = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stdout.read_to_string(&mut s);
        s
    });
    let err = std::thread::spawn(move || {
        let mut s = String::new();
        let _ = stderr.read_to_string(&mut s);
        s
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().map_err(|e| e.to_string())? {
            break status;
        }
        if start.elapsed() > BROWSER_TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!(
                "{} {args:?} ran past {BROWSER_TIMEOUT:?} and was killed",
                browser.display()
            ));
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let (out, err) = (out.join().unwrap(), err.join().unwrap());
    let _ = std::fs::remove_dir_all(&profile);
    if !status.success() {
        return Err(format!(
            "{} {args:?} exited with {status}:\n{err}",
            browser.display()
        ));
    }
    Ok(out)
}

/// Loads a test copy of `page` (beside it, so its relative links resolve) and returns the
/// probe's result: `(images, broken images, errors)`.
fn probe(browser: &Path, work: &Path, page: &Path) -> (usize, Vec<String>, Vec<String>) {
    let html = std::fs::read_to_string(page).unwrap();
    let probe = PROBE.replace("RESULT_ID", RESULT_ID);
    let at = html.find("<head>").expect("the page has a <head>") + "<head>".len();
    let copy = page.with_extension("browser-test.html");
    // Every image eager, so `load` waits for all of them (a lazy one below the fold would not
    // load in a headless window).
    let body = html[at..].replace("loading=\"lazy\"", "loading=\"eager\"");
    std::fs::write(&copy, format!("{}{probe}{body}", &html[..at])).unwrap();
    let url = format!("file://{}", copy.display());
    let dom = browse(
        browser,
        work,
        &[
            "--virtual-time-budget=15000".into(),
            "--dump-dom".into(),
            url.clone(),
        ],
    )
    .unwrap_or_else(|e| panic!("{}: {e}", page.display()));
    let _ = std::fs::remove_file(&copy);
    let start = dom
        .find(&format!("<pre id=\"{RESULT_ID}\">"))
        .unwrap_or_else(|| panic!("{url}: the probe wrote no result; the page's DOM:\n{dom}"));
    let rest = &dom[start..];
    let json = &rest[rest.find('>').unwrap() + 1..rest.find("</pre>").unwrap()];
    let json = json
        .replace("&quot;", "\"")
        .replace("&lt;", "<")
        .replace("&gt;", ">")
        .replace("&amp;", "&");
    let v: serde_json::Value = serde_json::from_str(&json).unwrap();
    let list = |k: &str| -> Vec<String> {
        v[k].as_array()
            .unwrap()
            .iter()
            .map(|s| s.as_str().unwrap_or_default().to_string())
            .collect()
    };
    (
        v["images"].as_u64().unwrap() as usize,
        list("broken"),
        list("errors"),
    )
}

#[test]
fn the_report_of_a_quick_sweep_loads_in_chromium_without_errors_and_every_image_decodes() {
    let Some(browser) = chromium() else {
        if std::env::var("FORESTLOD_ALLOW_NO_BROWSER").is_ok_and(|v| v == "1") {
            eprintln!("no Chromium; skipped (FORESTLOD_ALLOW_NO_BROWSER=1)");
            return;
        }
        panic!(
            "the browser test needs headless Chromium: run scripts/install-deps (as root: \
             apt-get install -y chromium), or point FORESTLOD_CHROMIUM at a Chromium binary; \
             FORESTLOD_ALLOW_NO_BROWSER=1 skips this test"
        );
    };
    let out = std::env::temp_dir().join(format!("forestlod-browser-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let start = Instant::now();
    run(&SweepArgs {
        file: Some("lod_settings".into()),
        out: out.clone(),
        quick: true,
        backend: Some("reference".into()),
        ..SweepArgs::default()
    })
    .expect("the quick sweep runs");
    write_report(&out).expect("the report is written");
    eprintln!(
        "quick sweep and report: {:.1} s",
        start.elapsed().as_secs_f64()
    );
    let index = out.join("index.html");
    let index_bytes = std::fs::metadata(&index).unwrap().len();
    assert!(index_bytes < 2 << 20, "index.html: {index_bytes} bytes");
    let mut pages = vec![index.clone()];
    for e in std::fs::read_dir(&out).unwrap() {
        let p = e.unwrap().path();
        let name = p.file_name().unwrap().to_string_lossy().into_owned();
        if name.starts_with("sweep-") && name.ends_with(".html") {
            pages.push(p);
        }
    }
    assert!(pages.len() >= 2, "no sweep page: {pages:?}");
    // The self-contained page for mailing too (images embedded).
    pages.push(out.join("report.html"));
    let work = out.join("browser");
    std::fs::create_dir_all(&work).unwrap();
    let mut failures = Vec::new();
    for page in &pages {
        let t = Instant::now();
        let (images, broken, errors) = probe(&browser, &work, page);
        eprintln!(
            "{}: {images} images, {} broken, {} errors ({:.1} s)",
            page.display(),
            broken.len(),
            errors.len(),
            t.elapsed().as_secs_f64()
        );
        if images == 0 || !broken.is_empty() || !errors.is_empty() {
            failures.push(format!(
                "{}: {images} images; broken {broken:?}; errors {errors:?}",
                page.display()
            ));
        }
    }
    // The first screen, for people (and the note).
    let shot = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("report-first-screen.png");
    let _ = std::fs::remove_file(&shot);
    browse(
        &browser,
        &work,
        &[
            format!("--screenshot={}", shot.display()),
            "--window-size=1280,800".into(),
            "--virtual-time-budget=5000".into(),
            format!("file://{}", index.display()),
        ],
    )
    .unwrap_or_else(|e| panic!("screenshot: {e}"));
    let png = image::open(&shot).expect("the screenshot is a PNG");
    assert_eq!((png.width(), png.height()), (1280, 800));
    eprintln!("first screen: {}", shot.display());
    let _ = std::fs::remove_dir_all(&out);
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}
