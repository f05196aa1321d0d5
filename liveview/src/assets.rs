//! The page's files, compiled in (no CDN: the page works on a bench PC with no network).

/// The run page.
pub(crate) const RUN_HTML: &str = include_str!("../assets/run.html");
/// The list of runs.
pub(crate) const RUNS_HTML: &str = include_str!("../assets/runs.html");

/// An asset by file name: its content type and bytes.
pub(crate) fn get(name: &str) -> Option<(&'static str, &'static [u8])> {
    Some(match name {
        "run.js" => ("text/javascript", include_bytes!("../assets/run.js")),
        "runs.js" => ("text/javascript", include_bytes!("../assets/runs.js")),
        "style.css" => ("text/css", include_bytes!("../assets/style.css")),
        "uPlot.iife.min.js" => (
            "text/javascript",
            include_bytes!("../assets/uPlot.iife.min.js"),
        ),
        "uPlot.min.css" => ("text/css", include_bytes!("../assets/uPlot.min.css")),
        "uPlot-LICENSE" => (
            "text/plain; charset=utf-8",
            include_bytes!("../assets/uPlot-LICENSE"),
        ),
        _ => return None,
    })
}
