//! One module per subcommand; each turns parsed arguments into library calls and output.

mod bench;
mod bench_fanout;
pub(crate) mod bench_ingest;
mod bench_link;
pub(crate) mod bench_replay;
mod certs;
pub mod cloud;
mod criticality;
mod deploy;
mod driver;
mod edge;
mod evaluate;
mod floor;
mod import;
mod input_file;
pub mod keys;
pub mod push;
mod recorded;
mod recordings;
pub(crate) mod recover;
mod regress;
mod risk_field;
mod router;
mod run;
mod run_progress;
mod scenarios;
mod scene;
mod simulate;
mod simulate_commonroad;
mod source;
mod train;
mod v2x;

use crate::cli::{
    BenchCommand, CertsCommand, Cli, Command, DeployCommand, EdgeCommand, ImportCommand, KeysCommand, ScenariosCommand,
    SceneCommand, V2xCommand,
};
use crate::error::CliResult;

pub fn dispatch(cli: Cli) -> CliResult {
    match cli.command {
        Command::Run(a) => run::run(a),
        Command::Scenarios(ScenariosCommand::Generate(a)) => scenarios::generate(a),
        Command::Scenarios(ScenariosCommand::Rank(a)) => scenarios::rank(a),
        Command::Scenarios(ScenariosCommand::Floor(a)) => floor::floor(a),
        Command::Scenarios(ScenariosCommand::Mutate(a)) => scenarios::mutate(a),
        Command::Scenarios(ScenariosCommand::Regress(a)) => regress::regress(a),
        Command::Simulate(a) => simulate::simulate(a),
        Command::Evaluate(a) => evaluate::evaluate(a),
        Command::Train(a) => train::train(a),
        Command::RiskField(a) => risk_field::risk_field(a),
        Command::Criticality(a) => criticality::criticality(a),
        Command::Import(ImportCommand::Commonroad(a)) => import::commonroad(a),
        Command::Recover(a) => recover::recover(a),
        Command::Recordings(c) => recordings::recordings(c),
        Command::Bench(BenchCommand::Sim(a)) => bench::sim(a),
        Command::Bench(BenchCommand::RiskField(a)) => bench::risk_field(a),
        Command::Bench(BenchCommand::Zenoh(a)) => cloud::bench_zenoh(a),
        Command::Bench(BenchCommand::Replay(a)) => bench_replay::replay(a),
        Command::Bench(BenchCommand::Ingest(a)) => bench_ingest::ingest(a),
        Command::Router(a) => router::router(a),
        Command::Edge(EdgeCommand::Vehicle(a)) => edge::vehicle(a),
        Command::Edge(EdgeCommand::Rsu(a)) => edge::rsu(a),
        Command::Edge(EdgeCommand::Replay(a)) => edge::replay(a),
        Command::Edge(EdgeCommand::Sensor(a)) => edge::sensor(a),
        Command::Edge(EdgeCommand::Gateway(a)) => edge::gateway(a),
        Command::Cloud(a) => cloud::cloud(a),
        Command::Push(c) => push::push(c),
        Command::Scene(SceneCommand::Run(a)) => scene::run(a),
        Command::Scene(SceneCommand::Authority(a)) => scene::authority(a),
        Command::Scene(SceneCommand::Vehicle(a)) => scene::participant(a, "vehicle"),
        Command::Scene(SceneCommand::Rsu(a)) => scene::participant(a, "rsu"),
        Command::Bench(BenchCommand::Latency(a)) => cloud::bench_latency(a),
        Command::Bench(BenchCommand::Warning(a)) => cloud::bench_warning(a),
        Command::Bench(BenchCommand::Fanout(a)) => bench_fanout::fanout(a),
        Command::Bench(BenchCommand::Link(a)) => bench_link::link(a),
        Command::Deploy(DeployCommand::Up(a)) => deploy::up(a),
        Command::Deploy(DeployCommand::Status(a)) => deploy::status(a),
        Command::Deploy(DeployCommand::Down(a)) => deploy::down(a),
        Command::Deploy(DeployCommand::Run(a)) => deploy::run(a),
        Command::V2x(V2xCommand::Channel(a)) => v2x::channel(a),
        Command::V2x(V2xCommand::Sweep(a)) => v2x::sweep(a),
        Command::Keys(KeysCommand::Generate(a)) => keys::generate(a),
        Command::Certs(CertsCommand::Init(a)) => certs::init(a),
        Command::Certs(CertsCommand::Issue(a)) => certs::issue(a),
    }
}
