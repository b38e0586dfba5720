// A Foxglove WebSocket client (the `@foxglove/ws-protocol` package, over `ws`) that subscribes to
// some of a server's channels and decodes what it receives with the schema each channel
// advertises (a protobuf FileDescriptorSet, decoded by protobufjs as the Foxglove app does).
//
//   node foxglove_client.js URL TIMEOUT_S TOPIC=COUNT...
//
// Prints one JSON line on stderr once connected ({"connected": true, ...}), and on stdout one per
// decoded message (its topic, channel encodings and a digest of its content) and a last line
// {"done": true|false, ...}. Exits 0 once every TOPIC has COUNT decoded messages, 1 at the
// timeout or on any error (a channel whose schema does not decode, a message that does not
// decode).
"use strict";

const { FoxgloveClient } = require("@foxglove/ws-protocol");
const WebSocket = require("ws");
const protobuf = require("protobufjs");
require("protobufjs/ext/descriptor");

const [url, timeoutArg, ...wantArgs] = process.argv.slice(2);
const want = new Map(
  wantArgs.map((arg) => {
    const at = arg.lastIndexOf("=");
    return [arg.slice(0, at), Number(arg.slice(at + 1))];
  }),
);
const got = new Map([...want.keys()].map((topic) => [topic, 0]));
const advertised = new Map(); // channel id -> channel
const subscribed = new Map(); // subscription id -> { channel, type }

function emit(line) {
  process.stdout.write(JSON.stringify(line) + "\n");
}

// Says how it went once, then closes the connection properly (a server logs a reset as an error).
let finished = false;
function finish(done, why) {
  if (finished) return;
  finished = true;
  emit({ done, why, got: Object.fromEntries(got), advertised: [...advertised.values()].map((c) => c.topic) });
  process.exitCode = done ? 0 : 1;
  clearTimeout(timer);
  try {
    ws.close(1000);
  } catch {
    // Not open yet: nothing to close.
  }
  setTimeout(() => process.exit(), 2000).unref();
}

// A digest of a decoded message (protobufjs names fields in camelCase): what the test checks against what the edges sent.
function digest(schemaName, object) {
  switch (schemaName) {
    case "foxglove.SceneUpdate":
      return {
        entities: (object.entities ?? []).map((e) => ({
          id: e.id,
          frame_id: e.frameId,
          cubes: (e.cubes ?? []).length,
          lines: (e.lines ?? []).length,
          points: (e.lines ?? []).reduce((n, l) => n + (l.points ?? []).length, 0),
        })),
      };
    case "foxglove.Grid": {
      const data = Buffer.from(object.data ?? []);
      const cells = [];
      const stride = object.cellStride ?? 0;
      for (let at = 0; stride > 0 && at + 4 <= data.length; at += stride) cells.push(data.readFloatLE(at));
      return {
        frame_id: object.frameId,
        column_count: object.columnCount ?? 0,
        row_stride: object.rowStride ?? 0,
        cell_stride: stride,
        data_bytes: data.length,
        fields: (object.fields ?? []).map((f) => f.name),
        cells: cells.length,
        finite_cells: cells.filter(Number.isFinite).length,
        max_cell: cells.reduce((m, v) => Math.max(m, v), -Infinity),
      };
    }
    default:
      // Small messages (a vehicle state, a risk report): the whole of it.
      return object;
  }
}

const timer = setTimeout(() => finish(false, `timed out after ${timeoutArg} s`), Number(timeoutArg) * 1000);

// `foxglove.sdk.v1` is the name the Foxglove SDK's servers give the protocol the package calls
// `foxglove.websocket.v1` (the same messages); offer both.
const ws = new WebSocket(url, ["foxglove.sdk.v1", FoxgloveClient.SUPPORTED_SUBPROTOCOL]);
const client = new FoxgloveClient({ ws });

client.on("error", (error) => finish(false, `client error: ${error?.message ?? error}`));
client.on("close", () => finish(false, "the server closed the connection"));
client.on("serverInfo", (info) =>
  process.stderr.write(JSON.stringify({ connected: true, protocol: ws.protocol, server: info.name }) + "\n"),
);
client.on("advertise", (channels) => {
  for (const channel of channels) {
    advertised.set(channel.id, channel);
    if (!want.has(channel.topic)) continue;
    let type;
    try {
      if (channel.encoding !== "protobuf" || channel.schemaEncoding !== "protobuf") {
        throw new Error(`encodings ${channel.encoding}/${channel.schemaEncoding}`);
      }
      const root = protobuf.Root.fromDescriptor(Buffer.from(channel.schema, "base64"));
      type = root.lookupType(channel.schemaName);
    } catch (error) {
      finish(false, `channel ${channel.topic}: schema ${channel.schemaName} unusable: ${error.message}`);
      return;
    }
    subscribed.set(client.subscribe(channel.id), { channel, type });
  }
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const sub = subscribed.get(subscriptionId);
  // Messages already on their way when it finished are not part of the answer.
  if (!sub || finished) return;
  const { channel, type } = sub;
  let object;
  try {
    const bytes = new Uint8Array(data.buffer, data.byteOffset, data.byteLength);
    object = type.toObject(type.decode(bytes), { longs: String, enums: String, bytes: Array, defaults: false });
  } catch (error) {
    finish(false, `message on ${channel.topic} does not decode as ${channel.schemaName}: ${error.message}`);
    return;
  }
  got.set(channel.topic, got.get(channel.topic) + 1);
  emit({
    topic: channel.topic,
    schema: channel.schemaName,
    encoding: channel.encoding,
    schema_encoding: channel.schemaEncoding,
    log_time_ns: String(timestamp),
    message: digest(channel.schemaName, object),
  });
  if ([...want].every(([topic, count]) => got.get(topic) >= count)) {
    finish(true, "every topic received");
  }
});
