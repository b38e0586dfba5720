import json, sys, threading
import zenoh
from mcap.reader import make_reader
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory

locator, schema_mcap, expected = sys.argv[1], sys.argv[2], int(sys.argv[3])
with open(schema_mcap, "rb") as f:
    schemas = make_reader(f).get_summary().schemas.values()
    data = next(s.data for s in schemas if s.name == "risktwin.v1.VehicleState")
pool = descriptor_pool.DescriptorPool()
for fd in descriptor_pb2.FileDescriptorSet.FromString(data).file:
    pool.AddSerializedFile(fd.SerializeToString())
types = {"state": "VehicleState", "can": "CanFrame", "perception": "ObjectList"}
classes = {"risktwin.v1." + t: message_factory.GetMessageClass(pool.FindMessageTypeByName("risktwin.v1." + t)) for t in types.values()}

conf = zenoh.Config()
conf.insert_json5("mode", '"client"')
conf.insert_json5("connect/endpoints", json.dumps([locator]))
conf.insert_json5("scouting/multicast/enabled", "false")
session = zenoh.open(conf)
counts, bad, wrong_tag, lock, done = {}, [], [], threading.Lock(), threading.Event()

def on_sample(sample):
    key = str(sample.key_expr)
    stream = key.rsplit("/", 1)[-1]
    # The type is read from the sample's encoding tag, as any outside client would.
    media, _, schema = str(sample.encoding).partition(";")
    if media != "application/protobuf" or schema != "risktwin.v1." + types[stream]:
        with lock:
            wrong_tag.append(str(sample.encoding))
        return
    msg = classes[schema].FromString(sample.payload.to_bytes())
    with lock:
        counts[stream] = counts.get(stream, 0) + 1
        if msg.header.source != key.split("/")[3]:
            bad.append(key)
        if sum(counts.values()) >= expected:
            done.set()

sub = session.declare_subscriber("risktwin/v1/*/*/*", on_sample)
print("ready", file=sys.stderr, flush=True)
done.wait(30)
print(json.dumps({"counts": counts, "source_mismatch": len(bad), "wrong_tag": wrong_tag[:5]}), flush=True)
sub.undeclare()
session.close()
