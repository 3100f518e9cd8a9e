// map_server files in the browser, for previews before anything is stored: the YAML, PGM
// and PPM images (browsers do not decode them), images the browser decodes, zips of a
// pair, and the conversion rule of Nav2's map_io as DESIGN.md states it (the server's
// maps/domain/mapfile.py applies the same rule when the upload is stored).

const f32 = Math.fround;
export const FREE = 0;
export const OCCUPIED = 100;
export const UNKNOWN = -1;

// ------------------------------------------------------------ YAML

/** The map_server keys of a YAML document; raises Error naming a missing or bad key. */
export function parseMapYaml(text) {
  const fields = {};
  for (const raw of text.split(/\r?\n/)) {
    const line = raw.replace(/\s+#.*$/, "").replace(/^#.*$/, "");
    const match = line.match(/^\s*([A-Za-z_]+)\s*:\s*(.*?)\s*$/);
    if (match) fields[match[1]] = scalar(match[2]);
  }
  const meta = {
    image: String(fields.image ?? ""),
    resolution: Number(fields.resolution),
    origin: Array.isArray(fields.origin) ? fields.origin.map(Number) : [],
    occupied_thresh: Number(fields.occupied_thresh),
    free_thresh: Number(fields.free_thresh),
    negate: fields.negate === true || fields.negate === 1 || fields.negate === "1",
    mode: String(fields.mode ?? "trinary").toLowerCase(),
  };
  checkMeta(meta);
  return meta;
}

function scalar(value) {
  const text = value.replace(/^(['"])(.*)\1$/, "$2");
  if (/^\[.*\]$/.test(text)) return text.slice(1, -1).split(",").map((item) => Number(item.trim()));
  if (/^(true|false)$/i.test(text)) return text.toLowerCase() === "true";
  return text !== "" && Number.isFinite(Number(text)) ? Number(text) : text;
}

function checkMeta(meta) {
  const problems = [];
  if (!meta.image) problems.push("image: is required");
  if (!(meta.resolution > 0)) problems.push("resolution: must be a positive number");
  if (meta.origin.length !== 3 || meta.origin.some((v) => !Number.isFinite(v))) problems.push("origin: must be a list of three numbers");
  for (const key of ["occupied_thresh", "free_thresh"]) {
    if (!(meta[key] >= 0 && meta[key] <= 1)) problems.push(`${key}: must be between 0 and 1`);
  }
  if (!["trinary", "scale", "raw"].includes(meta.mode)) problems.push("mode: must be trinary, scale or raw");
  if (problems.length) throw new Error(problems.join("; "));
}

// ------------------------------------------------------------ images

/** {width, height, grey: Uint8Array, alpha: Uint8Array|null} of an image file's bytes. */
export async function decodeImage(name, bytes) {
  const head = String.fromCharCode(bytes[0], bytes[1]);
  if (/^P[1-6]$/.test(head)) return decodeNetpbm(bytes);
  if (/\.tiff?$/i.test(name)) throw new Error("browsers cannot preview TIFF; upload it to have the server convert it");
  const bitmap = await createImageBitmap(new Blob([bytes]), { colorSpaceConversion: "none", premultiplyAlpha: "none" });
  const canvas = new OffscreenCanvas(bitmap.width, bitmap.height);
  const ctx = canvas.getContext("2d", { willReadFrequently: true });
  ctx.drawImage(bitmap, 0, 0);
  return fromRgba(bitmap.width, bitmap.height, ctx.getImageData(0, 0, bitmap.width, bitmap.height).data);
}

function fromRgba(width, height, rgba) {
  const grey = new Uint8Array(width * height);
  let alpha = null;
  for (let i = 0; i < grey.length; i += 1) {
    const [r, g, b, a] = [rgba[4 * i], rgba[4 * i + 1], rgba[4 * i + 2], rgba[4 * i + 3]];
    grey[i] = Math.floor((r * 299 + g * 587 + b * 114 + 500) / 1000);
    if (a < 255) {
      alpha = alpha || new Uint8Array(grey.length).fill(255);
      alpha[i] = a;
    }
  }
  return { width, height, grey, alpha };
}

/** PBM, PGM and PPM, plain (P1-P3) or binary (P4-P6); 16-bit samples scaled as Pillow does. */
export function decodeNetpbm(bytes) {
  const reader = new NetpbmReader(bytes);
  const kind = reader.token();
  const width = Number(reader.token());
  const height = Number(reader.token());
  const bits = kind === "P1" || kind === "P4";
  const maxval = bits ? 1 : Number(reader.token());
  if (!(width > 0 && height > 0 && maxval > 0)) throw new Error("the PGM header is not valid");
  const channels = kind === "P3" || kind === "P6" ? 3 : 1;
  const samples = reader.samples(kind, width * height * channels, maxval, width);
  // Bitmaps mark black with 1; wide samples become bytes as round(v / 257).
  const toByte = (v) => (bits ? (v ? 0 : 255) : maxval > 255 ? Math.floor((v + 128) / 257) : Math.round((v * 255) / maxval));
  if (channels === 1) return { width, height, grey: Uint8Array.from(samples, toByte), alpha: null };
  const rgba = new Uint8ClampedArray(width * height * 4);
  for (let i = 0; i < width * height; i += 1) {
    rgba.set([toByte(samples[3 * i]), toByte(samples[3 * i + 1]), toByte(samples[3 * i + 2]), 255], 4 * i);
  }
  return fromRgba(width, height, rgba);
}

class NetpbmReader {
  constructor(bytes) {
    this.bytes = bytes;
    this.at = 0;
  }

  token() {
    const b = this.bytes;
    for (;;) {
      while (this.at < b.length && /\s/.test(String.fromCharCode(b[this.at]))) this.at += 1;
      if (b[this.at] !== 35) break; // '#' starts a comment
      while (this.at < b.length && b[this.at] !== 10) this.at += 1;
    }
    const start = this.at;
    while (this.at < b.length && !/\s/.test(String.fromCharCode(b[this.at]))) this.at += 1;
    return String.fromCharCode(...b.subarray(start, this.at));
  }

  samples(kind, count, maxval, width) {
    if (["P1", "P2", "P3"].includes(kind)) return Array.from({ length: count }, () => Number(this.token()));
    this.at += 1; // the single whitespace after the header
    const b = this.bytes;
    if (kind === "P4") {
      const stride = Math.ceil(width / 8);
      return Array.from({ length: count }, (_, i) => (b[this.at + Math.floor(i / width) * stride + Math.floor((i % width) / 8)] >> (7 - (i % 8))) & 1);
    }
    if (maxval > 255) return Array.from({ length: count }, (_, i) => (b[this.at + 2 * i] << 8) | b[this.at + 2 * i + 1]);
    return b.subarray(this.at, this.at + count);
  }
}

// ------------------------------------------------------------ conversion

/** The cell value of each grey byte 0..255 under `meta`. */
export function cellTable(meta) {
  const table = new Int8Array(256);
  const free = f32(meta.free_thresh);
  const occupied = f32(meta.occupied_thresh);
  const span = f32(meta.occupied_thresh - meta.free_thresh);
  for (let g = 0; g < 256; g += 1) {
    if (meta.mode === "raw") {
      table[g] = g <= OCCUPIED ? g : UNKNOWN;
      continue;
    }
    const shade = f32(g / 255);
    const p = meta.negate ? shade : f32(1 - shade);
    if (p >= occupied) table[g] = OCCUPIED;
    else if (p <= free) table[g] = FREE;
    else if (meta.mode === "scale") table[g] = roundHalfAway(f32(f32(f32(p - free) / span) * 100));
    else table[g] = UNKNOWN;
  }
  return table;
}

function roundHalfAway(value) {
  const whole = Math.floor(value);
  return whole + (value - whole >= 0.5 ? 1 : 0);
}

/** The OccupancyGrid (row 0 at the bottom) of a decoded image under `meta`, and its counts. */
export function occupancyGrid(image, meta) {
  const { width, height, grey, alpha } = image;
  const table = cellTable(meta);
  const data = new Int8Array(width * height);
  const counts = { free: 0, occupied: 0, unknown: 0, other: 0 };
  for (let row = 0; row < height; row += 1) {
    const source = (height - 1 - row) * width;
    for (let col = 0; col < width; col += 1) {
      const see = alpha && alpha[source + col] < 255 && meta.mode !== "raw";
      const cell = see ? UNKNOWN : table[grey[source + col]];
      data[row * width + col] = cell;
      counts[cell === FREE ? "free" : cell === OCCUPIED ? "occupied" : cell === UNKNOWN ? "unknown" : "other"] += 1;
    }
  }
  return { info: { width, height, resolution: meta.resolution }, data, counts };
}

// ------------------------------------------------------------ zip archives

/** The files of a zip archive as {name: Uint8Array} (stored or deflated entries). */
export async function readZip(bytes) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  let end = bytes.length - 22;
  while (end >= 0 && view.getUint32(end, true) !== 0x06054b50) end -= 1;
  if (end < 0) throw new Error("not a zip archive");
  const entries = view.getUint16(end + 10, true);
  let at = view.getUint32(end + 16, true);
  const files = {};
  for (let i = 0; i < entries; i += 1) {
    const method = view.getUint16(at + 10, true);
    const size = view.getUint32(at + 20, true);
    const nameLength = view.getUint16(at + 28, true);
    const extra = view.getUint16(at + 30, true) + view.getUint16(at + 32, true);
    const local = view.getUint32(at + 42, true);
    const name = new TextDecoder().decode(bytes.subarray(at + 46, at + 46 + nameLength));
    const start = local + 30 + view.getUint16(local + 26, true) + view.getUint16(local + 28, true);
    const packed = bytes.subarray(start, start + size);
    if (!name.endsWith("/")) files[name.split("/").pop()] = method === 0 ? packed : await inflate(packed);
    at += 46 + nameLength + extra;
  }
  return files;
}

async function inflate(packed) {
  const stream = new Blob([packed]).stream().pipeThrough(new DecompressionStream("deflate-raw"));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}
