//! The HTTP server: a thread of its own with its own runtime (the run's clock, virtual or
//! real, never waits on a browser), bound to the address given — loopback unless the user
//! asks otherwise — and read-only: every route is a GET, nothing reaches a device.
//!
//! Routes: `/` (the list of runs, or straight to the one run), `/runs.json`,
//! `/run/{id}/` (the run page), `/run/{id}/state.json`, `/run/{id}/frame.png`,
//! `/run/{id}/overlay.json`, `/run/{id}/report/{file}` (the run's report), `/assets/{file}`.

use std::net::SocketAddr;
use std::path::{Component, Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};

use axum::Router;
use axum::extract::{Path as UrlPath, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Redirect, Response};
use axum::routing::get;
use serde::Serialize;

use crate::board::{Board, Overlay};
use crate::{LiveError, assets, overlay};

/// One run in the list.
#[derive(Debug, Clone, Serialize)]
pub struct RunEntry {
    /// Identifier in URLs (the run directory's name).
    pub id: String,
    /// Protocol.
    pub protocol: String,
    /// Status (`completed`, `running`, `interrupted`, …).
    pub status: String,
    /// Start, UTC.
    pub started: String,
    /// Steps completed and planned.
    pub steps: String,
    /// The run has a report already (else it is made when opened).
    pub has_report: bool,
}

/// What the server shows: the live run, or finished runs read from disk.
pub trait Library: Send + Sync + 'static {
    /// Runs to list.
    fn runs(&self) -> Vec<RunEntry>;
    /// The one run this library shows, when it shows one (`/` opens it, not a list).
    fn only(&self) -> Option<String> {
        None
    }
    /// The board of run `id`.
    fn board(&self, id: &str) -> Result<Arc<Board>, String>;
    /// The folder holding run `id`'s report (`report.html` and its figures), made if need be.
    fn report(&self, id: &str) -> Result<PathBuf, String>;
}

/// A running server; dropping it stops it.
pub struct Server {
    url: String,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Server {
    /// Binds `addr` (port 0: a free one) and serves `library` from a thread of its own.
    pub fn start(addr: SocketAddr, library: Arc<dyn Library>) -> Result<Self, LiveError> {
        let listener = std::net::TcpListener::bind(addr).map_err(|source| LiveError::Bind {
            addr: addr.to_string(),
            cause: source,
        })?;
        let bound = listener.local_addr().map_err(|source| LiveError::Bind {
            addr: addr.to_string(),
            cause: source,
        })?;
        listener
            .set_nonblocking(true)
            .map_err(|source| LiveError::Bind {
                addr: addr.to_string(),
                cause: source,
            })?;
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let app = router(library);
        let thread = std::thread::Builder::new()
            .name("live-view".into())
            .spawn(move || {
                let Ok(rt) = tokio::runtime::Builder::new_current_thread()
                    .enable_io()
                    .build()
                else {
                    return;
                };
                rt.block_on(async move {
                    let Ok(listener) = tokio::net::TcpListener::from_std(listener) else {
                        return;
                    };
                    let _ = axum::serve(listener, app)
                        .with_graceful_shutdown(async {
                            let _ = stopped.await;
                        })
                        .await;
                });
            })
            .map_err(|source| LiveError::Bind {
                addr: addr.to_string(),
                cause: source,
            })?;
        let host = match bound {
            SocketAddr::V6(a) => format!("[{}]", a.ip()),
            SocketAddr::V4(a) => a.ip().to_string(),
        };
        Ok(Self {
            url: format!("http://{host}:{}/", bound.port()),
            stop: Some(stop),
            thread: Some(thread),
        })
    }

    /// The page's address.
    pub fn url(&self) -> &str {
        &self.url
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// The server's state: the library and, per run, the last overlay it tracked.
struct App {
    library: Arc<dyn Library>,
    overlays: Mutex<Option<(String, Overlay)>>,
}

fn router(library: Arc<dyn Library>) -> Router {
    let app = Arc::new(App {
        library,
        overlays: Mutex::new(None),
    });
    Router::new()
        .route("/", get(index))
        .route("/runs.json", get(runs))
        .route(
            "/run/{id}",
            get(|UrlPath(id): UrlPath<String>| async move {
                Redirect::permanent(&format!("/run/{id}/"))
            }),
        )
        .route("/run/{id}/", get(|| async { html(assets::RUN_HTML) }))
        .route("/run/{id}/state.json", get(state))
        .route("/run/{id}/frame.png", get(frame))
        .route("/run/{id}/overlay.json", get(overlay_json))
        .route(
            "/run/{id}/report",
            get(|UrlPath(id): UrlPath<String>| async move {
                Redirect::permanent(&format!("/run/{id}/report/"))
            }),
        )
        .route("/run/{id}/report/", get(report_index))
        .route("/run/{id}/report/{*file}", get(report))
        .route("/assets/{file}", get(asset))
        .with_state(app)
}

fn html(body: &'static str) -> Response {
    ([(header::CONTENT_TYPE, "text/html; charset=utf-8")], body).into_response()
}

fn not_found(why: String) -> Response {
    (StatusCode::NOT_FOUND, why).into_response()
}

fn json<T: Serialize>(v: &T) -> Response {
    match serde_json::to_vec(v) {
        Ok(bytes) => (
            [
                (header::CONTENT_TYPE, "application/json"),
                (header::CACHE_CONTROL, "no-store"),
            ],
            bytes,
        )
            .into_response(),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

async fn index(State(app): State<Arc<App>>) -> Response {
    match app.library.only() {
        Some(id) => Redirect::temporary(&format!("/run/{id}/")).into_response(),
        None => html(assets::RUNS_HTML),
    }
}

async fn runs(State(app): State<Arc<App>>) -> Response {
    json(&app.library.runs())
}

async fn state(State(app): State<Arc<App>>, UrlPath(id): UrlPath<String>) -> Response {
    let lib = app.library.clone();
    // Reading a finished run from disk may take a moment: off the server's only thread.
    match tokio::task::spawn_blocking(move || lib.board(&id)).await {
        Ok(Ok(board)) => json(&board.snapshot()),
        Ok(Err(why)) => not_found(why),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

async fn frame(State(app): State<Arc<App>>, UrlPath(id): UrlPath<String>) -> Response {
    let lib = app.library.clone();
    let made = tokio::task::spawn_blocking(move || {
        let board = lib.board(&id)?;
        let (latest, _) = board.frames();
        let f = latest.ok_or_else(|| "no frame yet".to_string())?;
        overlay::png(&f)
    })
    .await;
    match made {
        Ok(Ok(png)) => (
            [
                (header::CONTENT_TYPE, "image/png"),
                (header::CACHE_CONTROL, "no-store"),
            ],
            png,
        )
            .into_response(),
        Ok(Err(why)) => not_found(why),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

async fn overlay_json(State(app): State<Arc<App>>, UrlPath(id): UrlPath<String>) -> Response {
    let app2 = app.clone();
    let made = tokio::task::spawn_blocking(move || {
        let board = app2.library.board(&id)?;
        let (latest, reference) = board.frames();
        let (Some(latest), Some(reference)) = (latest, reference) else {
            return Err("no frame yet".to_string());
        };
        if let Some(o) = board.overlay_of(latest.index) {
            return Ok(o);
        }
        let mut cache = app2.overlays.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((cid, o)) = cache.as_ref()
            && *cid == id
            && o.index == latest.index
        {
            return Ok(o.clone());
        }
        let o = overlay::track(&reference, &latest);
        *cache = Some((id, o.clone()));
        Ok(o)
    })
    .await;
    match made {
        Ok(Ok(o)) => json(&o),
        Ok(Err(why)) => not_found(why),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

/// `file` inside `dir`, or why not: only plain relative names below the folder (no `..`,
/// no absolute path, no link leading out of it).
pub(crate) fn inside(dir: &Path, file: &str) -> Result<PathBuf, String> {
    let rel = Path::new(file);
    if file.is_empty() || !rel.components().all(|c| matches!(c, Component::Normal(_))) {
        return Err(format!("`{file}`: not a file of the report"));
    }
    let (Ok(base), Ok(path)) = (dir.canonicalize(), dir.join(rel).canonicalize()) else {
        return Err(format!("`{file}`: no such file in the report"));
    };
    if !path.starts_with(&base) || !path.is_file() {
        return Err(format!("`{file}`: not a file of the report"));
    }
    Ok(path)
}

fn content_type(path: &Path) -> &'static str {
    match path.extension().and_then(|e| e.to_str()) {
        Some("html") => "text/html; charset=utf-8",
        Some("svg") => "image/svg+xml",
        Some("png") => "image/png",
        Some("json") => "application/json",
        Some("csv") | Some("md") | Some("txt") => "text/plain; charset=utf-8",
        _ => "application/octet-stream",
    }
}

async fn report(
    State(app): State<Arc<App>>,
    UrlPath((id, file)): UrlPath<(String, String)>,
) -> Response {
    let lib = app.library.clone();
    let found = tokio::task::spawn_blocking(move || {
        let dir = lib.report(&id)?;
        let path = inside(&dir, &file)?;
        std::fs::read(&path)
            .map(|bytes| (content_type(&path), bytes))
            .map_err(|e| format!("{}: {e}", path.display()))
    })
    .await;
    match found {
        Ok(Ok((kind, bytes))) => ([(header::CONTENT_TYPE, kind)], bytes).into_response(),
        Ok(Err(why)) => not_found(why),
        Err(e) => (StatusCode::INTERNAL_SERVER_ERROR, e.to_string()).into_response(),
    }
}

async fn report_index(app: State<Arc<App>>, UrlPath(id): UrlPath<String>) -> Response {
    report(app, UrlPath((id, "report.html".to_string()))).await
}

async fn asset(UrlPath(file): UrlPath<String>) -> Response {
    match assets::get(&file) {
        Some((kind, bytes)) => (
            [
                (header::CONTENT_TYPE, kind),
                (header::CACHE_CONTROL, "max-age=3600"),
            ],
            bytes,
        )
            .into_response(),
        None => not_found(format!("no asset `{file}`")),
    }
}

#[cfg(test)]
mod tests {
    use super::inside;

    #[test]
    fn only_files_below_the_report_folder_are_served() {
        let root = std::env::temp_dir().join(format!("liveview-inside-{}", std::process::id()));
        let dir = root.join("report");
        std::fs::create_dir_all(&dir).expect("dir");
        std::fs::write(dir.join("report.html"), "x").expect("file");
        std::fs::write(root.join("secret.txt"), "s").expect("file");
        assert!(inside(&dir, "report.html").is_ok());
        for bad in [
            "../secret.txt",
            "/etc/passwd",
            "",
            ".",
            "a/../../secret.txt",
        ] {
            assert!(inside(&dir, bad).is_err(), "{bad} was served");
        }
        std::os::unix::fs::symlink(root.join("secret.txt"), dir.join("link.txt")).expect("link");
        assert!(
            inside(&dir, "link.txt").is_err(),
            "a link out of the folder was followed"
        );
        let _ = std::fs::remove_dir_all(&root);
    }
}
