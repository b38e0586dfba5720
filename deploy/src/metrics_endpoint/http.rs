//! The endpoint's HTTP: `GET /metrics` (and `HEAD`) answered with the text exposition format,
//! one request per connection (`Connection: close`), which is all a scraper needs. A request
//! head is read up to [`MAX_HEAD_BYTES`] within [`READ_TIMEOUT`]; anything else is refused.

use metrics_exporter_prometheus::PrometheusHandle;
use std::net::TcpListener;
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;

/// The largest request head read (Prometheus sends a few hundred bytes).
const MAX_HEAD_BYTES: usize = 8192;

/// How long a client has to send its request head, and to take the answer.
const READ_TIMEOUT: Duration = Duration::from_secs(10);

/// How often the recorder's histograms are drained when nobody scrapes (keeps their buffers
/// bounded).
const UPKEEP_PERIOD: Duration = Duration::from_secs(5);

/// What a request asks for.
#[derive(Debug, PartialEq, Eq)]
enum Route {
    /// The metrics; `body: false` for `HEAD`.
    Metrics {
        body: bool,
    },
    NotFound,
    MethodNotAllowed,
    BadRequest,
}

/// Serves `listener` until the process ends; `scraped` is called after each `/metrics` answer
/// was written whole.
pub(super) fn serve(listener: TcpListener, handle: PrometheusHandle, scraped: impl Fn() + Send + Sync + 'static) {
    let runtime = match tokio::runtime::Builder::new_current_thread().enable_all().build() {
        Ok(r) => r,
        Err(e) => return tracing::error!("metrics: no runtime for the endpoint: {e}"),
    };
    let scraped = std::sync::Arc::new(scraped);
    runtime.block_on(async move {
        let listener = match tokio::net::TcpListener::from_std(listener) {
            Ok(l) => l,
            Err(e) => return tracing::error!("metrics: {e}"),
        };
        let upkeep = handle.clone();
        tokio::spawn(async move {
            let mut every = tokio::time::interval(UPKEEP_PERIOD);
            loop {
                every.tick().await;
                upkeep.run_upkeep();
            }
        });
        loop {
            let stream = match listener.accept().await {
                Ok((stream, _)) => stream,
                Err(e) => {
                    // Out of file descriptors, say: try again shortly rather than spin.
                    tracing::warn!("metrics: accept: {e}");
                    tokio::time::sleep(Duration::from_millis(100)).await;
                    continue;
                }
            };
            let (handle, scraped) = (handle.clone(), std::sync::Arc::clone(&scraped));
            tokio::spawn(async move {
                // A client that goes away or stalls costs it its answer, nothing more.
                let _ = tokio::time::timeout(READ_TIMEOUT, answer(stream, &handle, &*scraped)).await;
            });
        }
    });
}

/// Reads one request head from `stream` and answers it.
async fn answer(mut stream: TcpStream, handle: &PrometheusHandle, scraped: &(dyn Fn() + Sync)) -> std::io::Result<()> {
    let mut head = Vec::with_capacity(1024);
    let mut buf = [0u8; 1024];
    let route = loop {
        let n = stream.read(&mut buf).await?;
        if n == 0 {
            return Ok(());
        }
        head.extend_from_slice(&buf[..n]);
        if head.windows(4).any(|w| w == b"\r\n\r\n") {
            break route(&head);
        }
        if head.len() > MAX_HEAD_BYTES {
            break Route::BadRequest;
        }
    };
    let metrics = matches!(route, Route::Metrics { .. });
    let response = match route {
        Route::Metrics { body } => {
            risktwin_transport::metrics::refresh();
            let text = handle.render();
            let head = format!(
                "HTTP/1.1 200 OK\r\nContent-Type: text/plain; version=0.0.4; charset=utf-8\r\n\
                 Content-Length: {}\r\nConnection: close\r\n\r\n",
                text.len()
            );
            let mut response = head.into_bytes();
            if body {
                response.extend_from_slice(text.as_bytes());
            }
            response
        }
        Route::NotFound => plain("404 Not Found", "only /metrics is served here\n"),
        Route::MethodNotAllowed => plain("405 Method Not Allowed", "GET or HEAD /metrics\n"),
        Route::BadRequest => plain("400 Bad Request", "not an HTTP request head\n"),
    };
    stream.write_all(&response).await?;
    stream.shutdown().await?;
    // Once the scraper has it all: a role waiting for its last scrape may exit after this.
    if metrics {
        scraped();
    }
    Ok(())
}

/// A short plain-text answer with `status`.
fn plain(status: &str, text: &str) -> Vec<u8> {
    format!(
        "HTTP/1.1 {status}\r\nContent-Type: text/plain; charset=utf-8\r\nContent-Length: {}\r\n\
         Connection: close\r\n\r\n{text}",
        text.len()
    )
    .into_bytes()
}

/// The route of a request head (`METHOD TARGET HTTP/x.y`, the query ignored).
fn route(head: &[u8]) -> Route {
    let line = head.split(|b| *b == b'\n').next().unwrap_or_default();
    let Ok(line) = std::str::from_utf8(line) else { return Route::BadRequest };
    let mut parts = line.trim_end_matches('\r').split(' ');
    let (Some(method), Some(target), Some(version), None) = (parts.next(), parts.next(), parts.next(), parts.next())
    else {
        return Route::BadRequest;
    };
    if !version.starts_with("HTTP/1.") {
        return Route::BadRequest;
    }
    let path = target.split('?').next().unwrap_or_default();
    match (method, path) {
        ("GET", "/metrics") => Route::Metrics { body: true },
        ("HEAD", "/metrics") => Route::Metrics { body: false },
        (_, "/metrics") => Route::MethodNotAllowed,
        _ => Route::NotFound,
    }
}

#[cfg(test)]
mod tests {
    use super::{Route, route};

    #[test]
    fn requests_are_routed_by_method_and_path() {
        assert_eq!(route(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n"), Route::Metrics { body: true });
        assert_eq!(route(b"GET /metrics?x=1 HTTP/1.0\r\n\r\n"), Route::Metrics { body: true });
        assert_eq!(route(b"HEAD /metrics HTTP/1.1\r\n\r\n"), Route::Metrics { body: false });
        assert_eq!(route(b"POST /metrics HTTP/1.1\r\n\r\n"), Route::MethodNotAllowed);
        assert_eq!(route(b"GET / HTTP/1.1\r\n\r\n"), Route::NotFound);
        for bad in [
            &b"GET /metrics\r\n\r\n"[..],
            b"GET  /metrics HTTP/1.1\r\n\r\n",
            b"\xff\r\n\r\n",
            b"GET /metrics SPDY/3\r\n\r\n",
        ] {
            assert_ne!(route(bad), Route::Metrics { body: true }, "{bad:?}");
        }
    }
}
