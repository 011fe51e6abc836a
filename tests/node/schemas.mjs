// Schemas as Foxglove and Lichtblick read them, and decoders built from them.
//
// The JSON Schema check follows the rules of the parser both viewers use for a `jsonschema`
// channel (`parseJsonSchema` of their `mcap-support` package, not published on npm; the rules
// here are restated, not copied): the root and every nested object have `"type": "object"` and a
// `properties` object; every property has exactly one type, a string from boolean, string,
// number, integer, object, array; a string's `contentEncoding` is absent or base64; an array's
// `items` have one type from boolean, string, number, integer, object. A list of types, `null`,
// or a missing type is refused, as the viewers refuse the whole channel ("Failed to parse
// channel schema"). Protobuf schemas are read as the viewers read them: protobufjs' `Root` from
// the advertised `FileDescriptorSet`.

import protobuf from "protobufjs";
import descriptor from "protobufjs/ext/descriptor/index.js";

const FIELD_TYPES = ["boolean", "string", "number", "integer", "object", "array"];
const ITEM_TYPES = ["boolean", "string", "number", "integer", "object"];

/** Checks `schema` (a parsed JSON Schema) as the viewers parse it; throws naming the field. */
export function strictJsonSchema(schema, at) {
  if (schema === null || typeof schema !== "object" || schema.type !== "object") {
    throw new Error(`${at}: expected "type": "object", got ${JSON.stringify(schema?.type)}`);
  }
  if (schema.properties === null || typeof schema.properties !== "object") {
    throw new Error(`${at}: an object without "properties"`);
  }
  for (const [name, field] of Object.entries(schema.properties)) {
    const where = `${at}.${name}`;
    if (typeof field.type !== "string" || !FIELD_TYPES.includes(field.type)) {
      throw new Error(`${where}: unsupported field type ${JSON.stringify(field.type)}`);
    }
    if (field.type === "string" && ![undefined, "base64"].includes(field.contentEncoding)) {
      throw new Error(`${where}: unsupported contentEncoding ${field.contentEncoding}`);
    }
    if (field.type === "object") {
      strictJsonSchema(field, where);
    }
    if (field.type === "array") {
      const items = field.items;
      if (items === null || typeof items !== "object" || !ITEM_TYPES.includes(items.type)) {
        throw new Error(`${where}: unsupported array item type ${JSON.stringify(items?.type)}`);
      }
      if (items.type === "object") {
        strictJsonSchema(items, `${where}[]`);
      }
      if (items.type === "string" && items.contentEncoding !== undefined) {
        throw new Error(`${where}[]: unsupported contentEncoding for array item`);
      }
    }
  }
}

/** The problems of `value` against `schema` (types, required, no other field, enum, sizes). */
export function validate(value, schema, at = "$") {
  const bad = [];
  const type = schema.type;
  const ok = {
    object: () => value !== null && typeof value === "object" && !Array.isArray(value),
    array: () => Array.isArray(value),
    string: () => typeof value === "string",
    boolean: () => typeof value === "boolean",
    number: () => typeof value === "number" && Number.isFinite(value),
    integer: () => Number.isInteger(value),
  }[type];
  if (ok === undefined || !ok()) {
    return [`${at}: ${JSON.stringify(value)} is not a ${type}`];
  }
  if (schema.enum !== undefined && !schema.enum.includes(value)) {
    bad.push(`${at}: ${JSON.stringify(value)} is not one of ${JSON.stringify(schema.enum)}`);
  }
  if (type === "object") {
    for (const r of schema.required ?? []) {
      if (!(r in value)) bad.push(`${at}: missing required ${r}`);
    }
    for (const [k, v] of Object.entries(value)) {
      const p = schema.properties?.[k];
      if (p === undefined) {
        if (schema.additionalProperties === false) bad.push(`${at}: field ${k} not in the schema`);
      } else {
        bad.push(...validate(v, p, `${at}.${k}`));
      }
    }
  }
  if (type === "array") {
    if (schema.minItems !== undefined && value.length < schema.minItems) bad.push(`${at}: too short`);
    if (schema.maxItems !== undefined && value.length > schema.maxItems) bad.push(`${at}: too long`);
    value.forEach((v, i) => bad.push(...validate(v, schema.items, `${at}[${i}]`)));
  }
  return bad;
}

/**
 * A decoder for a channel of `messageEncoding` with schema `{name, encoding, data}` (`data`:
 * bytes), as a viewer builds it: returns `payload (Uint8Array) -> object`, throwing on a message
 * that does not decode or (JSON) does not match its schema.
 */
export function decoder(messageEncoding, schema) {
  if (messageEncoding === "json") {
    if (schema.encoding !== "jsonschema") {
      throw new Error(`json with schema encoding ${schema.encoding}`);
    }
    const parsed = JSON.parse(new TextDecoder().decode(schema.data));
    strictJsonSchema(parsed, schema.name);
    const text = new TextDecoder();
    return (payload) => {
      const m = JSON.parse(text.decode(payload));
      const bad = validate(m, parsed);
      if (bad.length > 0) throw new Error(bad.slice(0, 3).join("; "));
      return m;
    };
  }
  if (messageEncoding === "protobuf") {
    if (schema.encoding !== "protobuf") {
      throw new Error(`protobuf with schema encoding ${schema.encoding}`);
    }
    const root = protobuf.Root.fromDescriptor(descriptor.FileDescriptorSet.decode(schema.data));
    root.resolveAll();
    const type = root.lookupType(schema.name);
    return (payload) => type.toObject(type.decode(payload), { longs: Number, defaults: true });
  }
  throw new Error(`unsupported message encoding ${messageEncoding}`);
}
