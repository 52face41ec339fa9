#!/usr/bin/env node
// Independent MCAP reader for ppf_bag tests: reads FILE with @mcap/core (indexed reader, or the
// linear stream reader with --stream), decodes every message with @foxglove/rosmsg2-serialization
// using the schema text stored in the file, and prints one JSON line per message in log-time
// order: {"topic","schema","log_time","message"}. uint8[]/byte[] arrays are printed as
// {"length":N,"fnv1a":"xxxxxxxx"} (32-bit FNV-1a), int64/uint64 as strings.
// --schemas: instead, print one JSON line per schema, {"schema","encoding","fields":[root field
// names], "default_size"}, after parsing its text with @foxglove/rosmsg (checks the definitions themselves).
// Exit code 1 with a message on stderr for any read/CRC/decode error.
import { open, readFile } from "node:fs/promises";
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageReader, MessageWriter } from "@foxglove/rosmsg2-serialization";
import lz4 from "lz4js";
import zstd from "@foxglove/wasm-zstd";

const args = process.argv.slice(2);
const stream = args.includes("--stream");
const schemasOnly = args.includes("--schemas");
const file = args.find((a) => !a.startsWith("--"));
if (!file) {
  console.error("usage: mcap_dump.mjs FILE [--stream]");
  process.exit(2);
}

await zstd.isLoaded;
const decompressHandlers = {
  lz4: (buf, size) => {
    const out = lz4.decompress(buf, Number(size));
    return out instanceof Uint8Array ? out : Uint8Array.from(out);
  },
  zstd: (buf, size) => zstd.decompress(buf, Number(size)),
};

function fnv1a(bytes) {
  let h = 0x811c9dc5;
  for (const b of bytes) h = Math.imul(h ^ b, 0x01000193) >>> 0;
  return h.toString(16).padStart(8, "0");
}

function replacer(_key, value) {
  if (typeof value === "bigint") return value.toString();
  if (value instanceof Uint8Array || value instanceof Int8Array) {
    return { length: value.length, fnv1a: fnv1a(value) };
  }
  if (ArrayBuffer.isView(value)) return Array.from(value, (v) => (typeof v === "bigint" ? v.toString() : v));
  return value;
}

const decoders = new Map();
function decoderFor(schema) {
  if (!schema || schema.encoding !== "ros2msg") return undefined;
  let d = decoders.get(schema.id);
  if (!d) {
    const text = new TextDecoder().decode(schema.data);
    d = new MessageReader(parse(text, { ros2: true }));
    decoders.set(schema.id, d);
  }
  return d;
}

function line(channel, schema, msg) {
  const dec = decoderFor(schema);
  const message = dec ? dec.readMessage(msg.data) : { undecoded_length: msg.data.length };
  return JSON.stringify(
    { topic: channel.topic, schema: schema ? schema.name : "", log_time: msg.logTime, message },
    replacer,
  );
}

try {
  if (!stream) {
    const fh = await open(file, "r");
    const readable = {
      size: async () => BigInt((await fh.stat()).size),
      read: async (offset, size) => {
        const buf = Buffer.alloc(Number(size));
        const { bytesRead } = await fh.read(buf, 0, Number(size), Number(offset));
        if (bytesRead !== Number(size)) throw new Error(`short read at ${offset}`);
        return new Uint8Array(buf.buffer, buf.byteOffset, bytesRead);
      },
    };
    const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
    if (schemasOnly) {
      for (const schema of [...reader.schemasById.values()].sort((a, b) => a.id - b.id)) {
        const text = new TextDecoder().decode(schema.data);
        let fields = [];
        let default_size = 0;
        if (schema.encoding === "ros2msg") {
          const defs = parse(text, { ros2: true });
          fields = defs[0].definitions.filter((d) => !d.isConstant).map((d) => d.name);
          // Serializing a default message (one element in each top-level message array) and reading
          // it back resolves every nested type.
          const sample = {};
          for (const d of defs[0].definitions) {
            if (d.isArray && d.isComplex && !d.isConstant) sample[d.name] = [{}];
          }
          const bytes = new MessageWriter(defs).writeMessage(sample);
          new MessageReader(defs).readMessage(bytes);
          default_size = bytes.length;
        }
        console.log(JSON.stringify({ schema: schema.name, encoding: schema.encoding, fields, default_size }));
      }
      await fh.close();
      process.exit(0);
    }
    for await (const msg of reader.readMessages()) {
      const channel = reader.channelsById.get(msg.channelId);
      const schema = reader.schemasById.get(channel.schemaId);
      console.log(line(channel, schema, msg));
    }
    await fh.close();
  } else {
    const reader = new McapStreamReader({ decompressHandlers, validateCrcs: true });
    reader.append(new Uint8Array(await readFile(file)));
    const schemas = new Map();
    const channels = new Map();
    const messages = [];
    for (let rec; (rec = reader.nextRecord()); ) {
      if (rec.type === "Schema") schemas.set(rec.id, rec);
      else if (rec.type === "Channel") channels.set(rec.id, rec);
      else if (rec.type === "Message") messages.push(rec);
    }
    if (!reader.done()) throw new Error("stream reader did not reach the end of the file");
    // File order -> log-time order (stable), to match the indexed reader's output.
    messages.sort((a, b) => (a.logTime < b.logTime ? -1 : a.logTime > b.logTime ? 1 : 0));
    for (const msg of messages) {
      const channel = channels.get(msg.channelId);
      console.log(line(channel, schemas.get(channel.schemaId), msg));
    }
  }
} catch (e) {
  console.error(`mcap_dump: ${file}: ${e && e.message ? e.message : e}`);
  process.exit(1);
}
