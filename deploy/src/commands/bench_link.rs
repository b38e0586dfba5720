//! `risktwin bench link`: what a deployment's emulated link costs when it is configured to cost
//! nothing. The same echo process (a child of this binary) is reached directly and through a
//! relay at 0 ms (`crate::emulate::relay`, the code every link of a deployment runs); round trips
//! of one message and streaming throughput are measured on both paths in one run, and the
//! ratios printed. A round trip crosses the relay twice, so the cost of one crossing is half
//! the difference of the round trips.

use crate::cli::BenchLinkArgs;
use crate::emulate::relay::{self, LinkShape, LinkState, RelayCounts};
use crate::error::{CliError, CliResult};
use crate::output::{Format, print_json, print_table};
use serde::Serialize;
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpListener, TcpStream};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

#[derive(Debug, Serialize)]
struct PathFigures {
    round_trip_p50_us: f64,
    round_trip_p99_us: f64,
    throughput_mbps: f64,
}

#[derive(Debug, Serialize)]
struct LinkBench {
    message_bytes: usize,
    round_trips: u64,
    direct: PathFigures,
    relay: PathFigures,
    /// Half the difference of the round-trip medians: one crossing of the relay.
    added_p50_us_per_crossing: f64,
    /// Relay throughput / direct throughput.
    throughput_ratio: f64,
}

/// The echo process: echoes every byte of every connection.
fn echo(port: u16) -> CliResult {
    let listener = TcpListener::bind(("127.0.0.1", port)).map_err(CliError::runtime)?;
    for stream in listener.incoming().map_while(Result::ok) {
        std::thread::spawn(move || {
            let _ = stream.set_nodelay(true);
            let mut reader = stream.try_clone().expect("a socket clones");
            let mut writer = stream;
            let _ = std::io::copy(&mut reader, &mut writer);
        });
    }
    Ok(())
}

/// Kills the echo process however the benchmark ends.
struct EchoChild(Child);

impl Drop for EchoChild {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

fn measure(addr: SocketAddr, args: &BenchLinkArgs) -> CliResult<PathFigures> {
    let io = CliError::runtime;
    let mut stream = TcpStream::connect(addr).map_err(io)?;
    stream.set_nodelay(true).map_err(io)?;
    let message = vec![7u8; args.message_bytes];
    let mut back = vec![0u8; args.message_bytes];
    let mut rtts_us = Vec::with_capacity(args.round_trips as usize);
    // The first round trips warm the path up and are not counted.
    for k in 0..args.round_trips + 100 {
        let t = Instant::now();
        stream.write_all(&message).map_err(io)?;
        stream.read_exact(&mut back).map_err(io)?;
        if k >= 100 {
            rtts_us.push(t.elapsed().as_secs_f64() * 1e6);
        }
    }
    rtts_us.sort_by(f64::total_cmp);
    let at = |q: f64| rtts_us[((rtts_us.len() - 1) as f64 * q) as usize];
    // Streaming: one thread writes for the time, this one reads the echo back.
    let mut writer = stream.try_clone().map_err(io)?;
    let stream_for = Duration::from_secs_f64(args.stream_s);
    let written = std::thread::spawn(move || {
        let start = Instant::now();
        let mut sent = 0u64;
        while start.elapsed() < stream_for {
            if writer.write_all(&message).is_err() {
                break;
            }
            sent += message.len() as u64;
        }
        sent
    });
    let start = Instant::now();
    let mut received = 0u64;
    let mut buffer = vec![0u8; 64 * 1024];
    while start.elapsed() < stream_for {
        match stream.read(&mut buffer) {
            Ok(0) | Err(_) => break,
            Ok(n) => received += n as u64,
        }
    }
    let seconds = start.elapsed().as_secs_f64();
    stream.shutdown(std::net::Shutdown::Both).map_err(io)?;
    let _ = written.join();
    Ok(PathFigures {
        round_trip_p50_us: at(0.5),
        round_trip_p99_us: at(0.99),
        throughput_mbps: received as f64 * 8.0 / seconds / 1e6,
    })
}

pub fn link(args: BenchLinkArgs) -> CliResult {
    if let Some(port) = args.echo_port {
        return echo(port);
    }
    let fits = (1..=10_000_000).contains(&args.round_trips)
        && (1..=16 << 20).contains(&args.message_bytes)
        && args.stream_s > 0.0
        && args.stream_s <= 600.0;
    if !fits {
        let what = "--round-trips must lie in [1, 10^7], --message-bytes in [1, 16 MiB], --stream-s in (0, 600]";
        return Err(CliError::input(what));
    }
    let port = TcpListener::bind("127.0.0.1:0").and_then(|l| l.local_addr()).map_err(CliError::runtime)?.port();
    let exe = std::env::current_exe().map_err(CliError::runtime)?;
    let child = Command::new(exe)
        .args(["bench", "link", "--echo-port", &port.to_string()])
        .stdin(Stdio::null())
        .spawn()
        .map_err(CliError::runtime)?;
    let _echo = EchoChild(child);
    let direct_addr = SocketAddr::from(([127, 0, 0, 1], port));
    let deadline = Instant::now() + Duration::from_secs(10);
    while TcpStream::connect(direct_addr).is_err() {
        if Instant::now() > deadline {
            return Err(CliError::runtime("the echo process did not listen"));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
    let runtime = tokio::runtime::Builder::new_multi_thread().worker_threads(1).enable_all().build();
    let runtime = runtime.map_err(CliError::runtime)?;
    let (_state, state_rx) = tokio::sync::watch::channel(LinkState::Up(LinkShape::lan(256 * 1024)));
    let listen = SocketAddr::from(([127, 0, 0, 1], 0));
    let relay = runtime
        .block_on(relay::start(listen, direct_addr, state_rx, Arc::new(RelayCounts::default()), 1))
        .map_err(CliError::runtime)?;
    let direct = measure(direct_addr, &args)?;
    let relayed = measure(relay.addr, &args)?;
    let report = LinkBench {
        message_bytes: args.message_bytes,
        round_trips: args.round_trips,
        added_p50_us_per_crossing: (relayed.round_trip_p50_us - direct.round_trip_p50_us) / 2.0,
        throughput_ratio: relayed.throughput_mbps / direct.throughput_mbps,
        direct,
        relay: relayed,
    };
    match args.format {
        Format::Json => print_json(&report),
        Format::Table | Format::Csv => print_table(
            &["path", "round trip p50 µs", "round trip p99 µs", "throughput Mbit/s"],
            &[
                vec![
                    "direct".into(),
                    format!("{:.1}", report.direct.round_trip_p50_us),
                    format!("{:.1}", report.direct.round_trip_p99_us),
                    format!("{:.0}", report.direct.throughput_mbps),
                ],
                vec![
                    "relay 0 ms".into(),
                    format!("{:.1}", report.relay.round_trip_p50_us),
                    format!("{:.1}", report.relay.round_trip_p99_us),
                    format!("{:.0}", report.relay.throughput_mbps),
                ],
                vec![
                    format!("added per crossing {:.1} µs", report.added_p50_us_per_crossing),
                    String::new(),
                    String::new(),
                    format!("ratio {:.2}", report.throughput_ratio),
                ],
            ],
        ),
    }
}
