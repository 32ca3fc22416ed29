"""Decoding Foxglove's protobuf messages the way Foxglove does: from the schema the message
carries (a FileDescriptorSet), into a plain dict."""

from __future__ import annotations

from typing import Any

from google.protobuf import descriptor_pb2, descriptor_pool, json_format, message_factory


def decode(schema_name: str, descriptor_set: bytes, payload: bytes) -> dict[str, Any]:
    pool = descriptor_pool.DescriptorPool()
    for file in descriptor_pb2.FileDescriptorSet.FromString(descriptor_set).file:
        pool.Add(file)
    cls = message_factory.GetMessageClass(pool.FindMessageTypeByName(schema_name))
    return json_format.MessageToDict(
        cls.FromString(payload), always_print_fields_with_no_presence=True
    )


def decode_message(message: Any) -> dict[str, Any]:
    """A ``foxglove.messages`` object as Foxglove reads it off the wire."""
    schema = message.get_schema()
    return decode(schema.name, schema.data, message.encode())
