"""Reading MCAP recordings back in the tests: the Foxglove schemas' protobuf classes."""
from pathlib import Path

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory


def proto_class(schema_name: str, descriptor_set: bytes):
    """The protobuf message class of ``schema_name`` from a serialised FileDescriptorSet."""
    pool = descriptor_pool.DescriptorPool()
    for fd in descriptor_pb2.FileDescriptorSet.FromString(descriptor_set).file:
        pool.Add(fd)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))


def read_mcap(path):
    """An MCAP file through the `mcap` reader (independent of psvs): ({topic: (schema name, message
    encoding)}, {topic: message count}, [(schema, channel, message)] in the file's order, so a test of rising
    time stamps tests the file)."""
    from mcap.reader import make_reader
    with Path(path).open("rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        topics = {c.topic: (summary.schemas[c.schema_id].name, c.message_encoding) for c in summary.channels.values()}
        counts = {summary.channels[k].topic: n for k, n in summary.statistics.channel_message_counts.items()}
        return topics, counts, list(reader.iter_messages(log_time_order=False))
