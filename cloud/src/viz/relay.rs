//! The task between the [`super::VizFeed`] and the Foxglove server: one raw channel per topic
//! (message encoding `protobuf`, the schema named as the recording names it, schema data the
//! crate's FileDescriptorSet, as in an MCAP recording), the already encoded bytes logged on it
//! as they are; and every site's road, republished every [`ROAD_PERIOD`] so that a client that
//! connects later sees it too (the protocol keeps no last message).

use super::feed::{VizMessage, VizShared, count};
use foxglove::{ChannelBuilder, Context, PartialMetadata, RawChannel, Schema};
use risktwin_common::road::Road;
use risktwin_protos::FILE_DESCRIPTOR_SET;
use risktwin_protos::convert::foxglove::{FOXGLOVE_SCENE_UPDATE, road_scene};
use risktwin_transport::SiteId;
use risktwin_transport::keyexpr::{CloudOutput, cloud_output, parse_cloud_output_key};
use risktwin_transport::wall_clock::unix_ns;
use std::collections::{BTreeSet, HashMap};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::mpsc::{Receiver, UnboundedReceiver};

/// How often every site's road is sent again.
pub(crate) const ROAD_PERIOD: Duration = Duration::from_secs(1);

/// The relay's state: the channels made so far and the roads to show.
pub(crate) struct Relay {
    context: Arc<Context>,
    channels: HashMap<String, Arc<RawChannel>>,
    /// The road of a site whose scene published none (`--road`).
    default_road: Road,
    /// Roads of the sites whose scene published a road map.
    site_roads: HashMap<String, Road>,
    /// Sites seen in the twin's scenes or with a road map.
    sites: BTreeSet<String>,
    shared: Arc<VizShared>,
}

impl Relay {
    pub(crate) fn new(context: Arc<Context>, default_road: Road, shared: Arc<VizShared>) -> Self {
        Relay {
            context,
            channels: HashMap::new(),
            default_road,
            site_roads: HashMap::new(),
            sites: BTreeSet::new(),
            shared,
        }
    }

    /// Relays until both inputs close (the task is aborted at shutdown before that).
    pub(crate) async fn run(
        mut self,
        mut messages: Receiver<VizMessage>,
        mut roads: UnboundedReceiver<(String, Road)>,
    ) {
        let mut every = tokio::time::interval(ROAD_PERIOD);
        every.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
        loop {
            tokio::select! {
                Some(message) = messages.recv() => self.relay(&message),
                Some((site, road)) = roads.recv() => {
                    self.site_roads.insert(site.clone(), road);
                    self.sites.insert(site.clone());
                    self.send_road(&site);
                }
                _ = every.tick() => {
                    let sites: Vec<String> = self.sites.iter().cloned().collect();
                    for site in &sites {
                        self.send_road(site);
                    }
                }
                else => return,
            }
        }
    }

    fn relay(&mut self, message: &VizMessage) {
        let topic = message.topic();
        if let Some(site) = parse_cloud_output_key(topic, CloudOutput::Scene)
            && !self.sites.contains(site)
        {
            self.sites.insert(site.to_owned());
            self.send_road(site);
        }
        self.log(topic, message.schema, message.log_time_ns, message.payload());
    }

    /// Sends `site`'s road, when a client subscribed to it (encoding it costs a few hundred µs).
    fn send_road(&mut self, site: &str) {
        let Ok(id) = SiteId::new(site) else { return };
        let topic = cloud_output(&id, CloudOutput::Road);
        let Some(channel) = self.channel(&topic, FOXGLOVE_SCENE_UPDATE) else { return };
        if !channel.has_sinks() {
            return;
        }
        let now_ns = unix_ns() as u64;
        let road = self.site_roads.get(site).unwrap_or(&self.default_road);
        let update = road_scene(now_ns as i64, road);
        self.log(&topic, FOXGLOVE_SCENE_UPDATE, now_ns, &prost::Message::encode_to_vec(&update));
    }

    /// Logs `payload` on `topic` when a client subscribed to it, and counts it.
    fn log(&mut self, topic: &str, schema: &'static str, log_time_ns: u64, payload: &[u8]) {
        let Some(channel) = self.channel(topic, schema) else { return };
        if channel.has_sinks() {
            channel.log_with_meta(payload, PartialMetadata::with_log_time(log_time_ns));
            count(&mut self.shared.counts().sent, topic);
        }
    }

    /// The channel of `topic`, made (and advertised to every client) on its first message.
    fn channel(&mut self, topic: &str, schema: &'static str) -> Option<Arc<RawChannel>> {
        if let Some(channel) = self.channels.get(topic) {
            return Some(Arc::clone(channel));
        }
        let built = ChannelBuilder::new(topic)
            .context(&self.context)
            .message_encoding("protobuf")
            .schema(Schema::new(schema, "protobuf", FILE_DESCRIPTOR_SET))
            .build_raw();
        match built {
            Ok(channel) => {
                self.channels.insert(topic.to_owned(), Arc::clone(&channel));
                Some(channel)
            }
            Err(e) => {
                // Only a missing message encoding fails, which is set above.
                tracing::warn!("viz: no channel for {topic}: {e}");
                None
            }
        }
    }
}
