#!/usr/bin/env python3
"""Reads a windcell recording with the MCAP reference reader (PyPI `mcap`) and decodes every
message with its schema.

    python3 scripts/check_mcap.py RUN.mcap            # a finished recording (summary, indexes)
    python3 scripts/check_mcap.py --recover RUN.mcap  # a recording cut off (kill -9): reads the
                                                      # records in file order up to the cut

Prints one line: `messages N topics T` (and `cut at byte B` when recovering). JSON messages are
parsed; protobuf messages (Foxglove's well-known schemas) are checked against their schema's
encoding and, when the `protobuf` package is installed, decoded from the FileDescriptorSet the
schema carries. Exit 1 on any message that does not decode.
"""
import json
import sys

from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from mcap.records import Channel, Message, Schema


def protobuf_decoder(schema):
    try:
        from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
    except ImportError:
        return None
    fds = descriptor_pb2.FileDescriptorSet.FromString(schema.data)
    pool = descriptor_pool.DescriptorPool()
    for f in fds.file:
        pool.Add(f)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema.name))
    return cls.FromString


def check(schema, data):
    if schema is None:
        return
    if schema.encoding == "jsonschema":
        json.loads(data)
    elif schema.encoding == "protobuf":
        decode = protobuf_decoder(schema)
        if decode is not None:
            decode(data)
        elif not schema.data:
            raise ValueError(f"protobuf schema {schema.name} carries no descriptor")
    else:
        raise ValueError(f"unknown schema encoding {schema.encoding}")


def main(argv):
    recover = "--recover" in argv
    paths = [a for a in argv if not a.startswith("--")]
    if len(paths) != 1:
        print(__doc__, file=sys.stderr)
        return 2
    path = paths[0]
    topics = set()
    count = 0
    with open(path, "rb") as f:
        if not recover:
            reader = make_reader(f)
            for schema, channel, message in reader.iter_messages():
                check(schema, message.data)
                topics.add(channel.topic)
                count += 1
            print(f"messages {count} topics {len(topics)}")
            return 0
        # Recovery: the records in file order; chunks are read whole, so a cut inside a chunk
        # loses that chunk (at most the last second of the run) and nothing before it.
        schemas, channels = {}, {}
        stream = StreamReader(f, skip_magic=False)
        try:
            for record in stream.records:
                if isinstance(record, Schema):
                    schemas[record.id] = record
                elif isinstance(record, Channel):
                    channels[record.id] = record
                elif isinstance(record, Message):
                    channel = channels[record.channel_id]
                    check(schemas.get(channel.schema_id), record.data)
                    topics.add(channel.topic)
                    count += 1
        except Exception as e:  # the cut: a truncated record
            print(f"cut at byte {f.tell()}: {type(e).__name__}", file=sys.stderr)
        print(f"messages {count} topics {len(topics)}")
        return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
