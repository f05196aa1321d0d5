"""Reads a gelrig MCAP export with the independent Python readers (mcap, mcap-ros2-support)
and prints, as JSON, the message count per topic, every /force message's time and wrench,
each frame's time, format and byte count, the first stage, step and marker messages, the attachments
and the metadata. Used by tests/e2e/export.rs."""
import sys, json
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
counts = {}; first = {}; forces = []; images = []
with open(sys.argv[1], "rb") as f:
    r = make_reader(f, decoder_factories=[DecoderFactory()])
    for schema, channel, message, msg in r.iter_decoded_messages():
        t = channel.topic
        counts[t] = counts.get(t, 0) + 1
        if t == "/force":
            forces.append([message.log_time, msg.header.stamp.sec, msg.header.stamp.nanosec,
                           msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z,
                           msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z])
        if t == "/camera/image/compressed":
            images.append([message.log_time, msg.format, len(msg.data)])
        if t not in first:
            if t == "/force":
                first[t] = dict(t=message.log_time, sec=msg.header.stamp.sec, ns=msg.header.stamp.nanosec,
                    f=[msg.wrench.force.x, msg.wrench.force.y, msg.wrench.force.z], tq=[msg.wrench.torque.x, msg.wrench.torque.y, msg.wrench.torque.z])
            elif t == "/camera/image/compressed":
                first[t] = dict(t=message.log_time, format=msg.format, n=len(msg.data), png=bytes(msg.data[:4]).hex())
            elif t == "/stages":
                first[t] = dict(t=message.log_time, name=list(msg.name), pos=list(msg.position))
            elif t in ("/steps", "/tactile"):
                first[t] = json.loads(msg.data)
            elif t == "/camera/markers":
                first[t] = dict(t=message.log_time, ns=msg.ns, id=msg.id, type=msg.type,
                    n=len(msg.points), p0=[msg.points[0].x, msg.points[0].y] if msg.points else None,
                    p1=[msg.points[1].x, msg.points[1].y] if msg.points else None)
    f.seek(0)
    r = make_reader(f)
    atts = [a.name for a in r.iter_attachments()]
    meta = [dict(m.metadata) for m in r.iter_metadata()]
print(json.dumps(dict(counts=counts, first=first, forces=forces, images=images, attachments=atts, metadata=meta), default=str))
