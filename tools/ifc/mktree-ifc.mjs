#!/usr/bin/env node
// mktree's IFC reader: reads an IFC file (2x3, 4, 4.3) with web-ifc and writes its products to stdout as
// an "MKIFCS" object stream (format below) that engine/scene/ifc_reader.cc reads.
//
// Usage: node mktree-ifc.mjs FILE.ifc > stream      (exit 0: stream complete; 2: the file cannot be read)
//
// One object per IFC product with a body representation: web-ifc's geometry of the product (openings
// subtracted, every mapped item and representation item merged under the product). Coordinates in the
// IFC model's frame (Z up), in metres, with IfcMapConversion applied where the file has one: web-ifc hands
// out a Y-up frame for viewers, (x, y, z)_ifc -> (x, z, -y), undone here exactly (a permutation and a sign).
//
// Stream (all integers and floats little-endian; strings UTF-8 with a u32 byte length before them):
//   header : "MKIFCS\0\0", u32 version (= 1), u32 flags (= 0)
//   object : "MKOB", str name, u32 attribute_count, (str key, str value) * attribute_count,
//            u32 vertex_count, u32 triangle_count, f64 vertices[3 * vertex_count],
//            u32 triangles[3 * triangle_count]
//   warning: "MKWN", str text      (a product web-ifc made no geometry for, and the like; the rest is built)
//   error  : "MKER", str text      (the file cannot be read; nothing follows but the end record)
//   end    : "MKEN", u32 0, u64 objects written
// A stream without an end record was cut short (the program died): the reader treats it as an error, as it
// does an error record. stderr carries only what Node itself prints when it fails.
import fs from 'node:fs';
import { createRequire } from 'node:module';

const FILE = process.argv[2];
const OUT_FD = 1;
const STREAM_VERSION = 1;

// ---- the stream -------------------------------------------------------------------------------------
class StreamWriter {
  constructor(fd) {
    this.fd = fd;
    this.buf = Buffer.allocUnsafe(1 << 20);
    this.at = 0;
    this.objects = 0;
  }
  room(n) {
    if (this.at + n <= this.buf.length) return;
    this.flush();
    if (n > this.buf.length) this.buf = Buffer.allocUnsafe(n);
  }
  u32(v) {
    this.room(4);
    this.at = this.buf.writeUInt32LE(v >>> 0, this.at);
  }
  u64(v) {
    this.room(8);
    this.at = this.buf.writeBigUInt64LE(BigInt(v), this.at);
  }
  tag(t) { this.push(Buffer.from(t, 'latin1')); }
  str(s) {
    const text = String(s);
    const n = Buffer.byteLength(text, 'utf8');
    this.u32(n);
    this.room(n);
    this.at += this.buf.write(text, this.at, 'utf8');
  }
  push(b) {
    this.room(b.length);
    b.copy(this.buf, this.at);
    this.at += b.length;
  }
  flush() {
    for (let at = 0; at < this.at;) {
      try {
        at += fs.writeSync(this.fd, this.buf, at, this.at - at);
      } catch (e) {
        if (e.code !== 'EAGAIN') throw e;
        Atomics.wait(new Int32Array(new SharedArrayBuffer(4)), 0, 0, 1);  // a non-blocking pipe is full
      }
    }
    this.at = 0;
  }
  header() {
    this.tag('MKIFCS\0\0');
    this.u32(STREAM_VERSION);
    this.u32(0);
  }
  object(name, attributes, vertices, triangles) {
    this.tag('MKOB');
    this.str(name);
    this.u32(attributes.length);
    for (const [k, v] of attributes) {
      this.str(k);
      this.str(v);
    }
    this.u32(vertices.length / 3);
    this.u32(triangles.length / 3);
    this.push(Buffer.from(vertices.buffer, vertices.byteOffset, vertices.byteLength));
    this.push(Buffer.from(triangles.buffer, triangles.byteOffset, triangles.byteLength));
    ++this.objects;
  }
  warning(text) {
    this.tag('MKWN');
    this.str(text);
  }
  error(text) {
    this.tag('MKER');
    this.str(text);
  }
  end() {
    this.tag('MKEN');
    this.u32(0);
    this.u64(this.objects);
    this.flush();
  }
}

const out = new StreamWriter(OUT_FD);

// Ends the stream with an error record: the file cannot be read.
function fail(text) {
  out.error(text);
  out.end();
  process.exit(2);
}

// ---- reading the file -------------------------------------------------------------------------------
const SCHEMAS = { IFC2X3: 'IFC2X3', IFC4: 'IFC4', IFC4X3: 'IFC4X3' };

// The FILE_SCHEMA of a STEP header and whether the file ends as a STEP file must ("END-ISO-10303-21;").
function CheckStepFile(data) {
  const head = data.subarray(0, Math.min(data.length, 1 << 16)).toString('latin1');
  if (!/^\s*ISO-10303-21\s*;/.test(head)) fail('not an IFC file: no ISO-10303-21 header');
  const m = /FILE_SCHEMA\s*\(\s*\(\s*'([^']*)'/i.exec(head);
  if (!m) fail('not an IFC file: no FILE_SCHEMA in the header');
  const declared = m[1].toUpperCase();
  const family = /^IFC4X3(_|$)/.test(declared) ? 'IFC4X3' : SCHEMAS[declared];
  if (!family)
    fail(`unsupported IFC schema '${m[1]}' (web-ifc reads IFC2X3, IFC4 and IFC4X3)`);
  const tail = data.subarray(Math.max(0, data.length - 4096)).toString('latin1');
  if (!/END-ISO-10303-21\s*;\s*$/.test(tail))
    fail('truncated: the file does not end with END-ISO-10303-21; (cut short or damaged)');
  return [family, m[1]];
}

if (!FILE) {
  process.stderr.write('usage: node mktree-ifc.mjs FILE.ifc > stream\n');
  process.exit(64);
}
out.header();
// Anything that escapes (web-ifc throwing on an entity it cannot decode, ...) ends the stream with an
// error record rather than a stack trace and a cut stream.
process.on('uncaughtException', (e) => fail(`reading failed: ${e && e.message ? e.message : e}`));
let data;
try {
  data = fs.readFileSync(FILE);
} catch (e) {
  fail(`cannot read: ${e.message}`);
}
const [schema, declaredSchema] = CheckStepFile(data);
let W;
try {
  // require, not import: Node's ESM loader scans this large CommonJS module for its exports first.
  W = createRequire(import.meta.url)('web-ifc');
} catch (e) {
  fail(`web-ifc is not installed next to ${import.meta.url.replace('file://', '')}: ` +
       'run scripts/setup.sh (npm ci --prefix tools/ifc)');
}

// web-ifc logs through console.log: keep stdout for the stream.
console.log = console.error;
const api = new W.IfcAPI();
await api.Init();
api.SetLogLevel(W.LogLevel.LOG_LEVEL_OFF);
let model = -1;
try {
  model = api.OpenModel(data, { COORDINATE_TO_ORIGIN: false });
} catch (e) {
  fail(`web-ifc cannot parse the file: ${e.message ?? e}`);
}
data = null;
if (model < 0) fail(`unsupported IFC schema '${declaredSchema}': web-ifc ${api.GetVersion()} cannot open the file`);

// ---- entity access ----------------------------------------------------------------------------------
const lineCache = new Map();
function Line(id) {
  let l = lineCache.get(id);
  if (l === undefined) {
    try {
      l = api.GetLine(model, id);
    } catch (e) {
      l = null;
    }
    lineCache.set(id, l);
  }
  return l;
}
function Ref(v) { return v && v.type === 5 ? v.value : null; }
function Refs(v) {
  if (Array.isArray(v)) return v.map(Ref).filter((x) => x !== null);
  const r = Ref(v);
  return r === null ? [] : [r];
}
function TypeName(id) { return api.GetNameFromTypeCode(api.GetLineType(model, id)).toUpperCase(); }
function IdsOf(type) {
  const v = api.GetLineIDsWithType(model, type, true);
  const ids = [];
  for (let i = 0; i < v.size(); ++i) ids.push(v.get(i));
  return ids;
}
// A value of an attribute (IfcLabel, IfcLengthMeasure, a select, an enum) as text, or null.
function Text(v) {
  if (v === null || v === undefined) return null;
  if (Array.isArray(v)) {
    const parts = v.map(Text).filter((x) => x !== null);
    return parts.length ? parts.join(', ') : null;
  }
  if (typeof v !== 'object') return String(v);
  if (v.type === 5) return null;  // a reference, not a value
  if (v.value !== undefined && v.value !== null) {
    if (v.type === 3) {  // an enumeration or a boolean
      if (v.value === 'T') return 'true';
      if (v.value === 'F') return 'false';
      if (v.value === 'U') return 'unknown';
    }
    return String(v.value);
  }
  if (v._representationValue !== undefined) return String(v._representationValue);
  return null;
}
function GlobalId(id) {
  const l = Line(id);
  return l && l.GlobalId ? Text(l.GlobalId) : null;
}

// ---- relations --------------------------------------------------------------------------------------
const container = new Map();   // element -> spatial element containing it
const aggregate = new Map();   // part -> whole (IfcRelAggregates, IfcRelNests)
const voids = new Map();       // opening -> element it voids
const fills = new Map();       // door/window -> opening it fills
const materials = new Map();   // object -> [material names]
const psets = new Map();       // object -> [[key, value]]
const typeOf = new Map();      // object -> its type object (IfcRelDefinesByType)

function Push(map, key, value) {
  const a = map.get(key);
  if (a) a.push(value);
  else map.set(key, [value]);
}

for (const r of IdsOf(W.IFCRELCONTAINEDINSPATIALSTRUCTURE)) {
  const l = Line(r);
  for (const e of Refs(l.RelatedElements)) container.set(e, Ref(l.RelatingStructure));
}
for (const type of [W.IFCRELAGGREGATES, W.IFCRELNESTS]) {
  for (const r of IdsOf(type)) {
    const l = Line(r);
    for (const e of Refs(l.RelatedObjects)) aggregate.set(e, Ref(l.RelatingObject));
  }
}
for (const r of IdsOf(W.IFCRELVOIDSELEMENT)) {
  const l = Line(r);
  voids.set(Ref(l.RelatedOpeningElement), Ref(l.RelatingBuildingElement));
}
for (const r of IdsOf(W.IFCRELFILLSELEMENT)) {
  const l = Line(r);
  fills.set(Ref(l.RelatedBuildingElement), Ref(l.RelatingOpeningElement));
}
if (W.IFCRELDEFINESBYTYPE) {
  for (const r of IdsOf(W.IFCRELDEFINESBYTYPE)) {
    const l = Line(r);
    for (const e of Refs(l.RelatedObjects)) typeOf.set(e, Ref(l.RelatingType));
  }
}

// The names of the materials of a material definition (a material, list, layer set (usage), profile set
// (usage), constituent set).
function MaterialNames(id, depth = 0) {
  const l = Line(id);
  if (!l || depth > 4) return [];
  const t = TypeName(id);
  const name = Text(l.Name);
  switch (t) {
    case 'IFCMATERIAL':
      return name ? [name] : [];
    case 'IFCMATERIALLIST':
      return Refs(l.Materials).flatMap((m) => MaterialNames(m, depth + 1));
    case 'IFCMATERIALLAYERSETUSAGE':
      return MaterialNames(Ref(l.ForLayerSet), depth + 1);
    case 'IFCMATERIALLAYERSET':
      return Refs(l.MaterialLayers).flatMap((m) => MaterialNames(m, depth + 1));
    case 'IFCMATERIALLAYER':
    case 'IFCMATERIALPROFILE':
    case 'IFCMATERIALCONSTITUENT':
      return MaterialNames(Ref(l.Material), depth + 1);
    case 'IFCMATERIALPROFILESETUSAGE':
      return MaterialNames(Ref(l.ForProfileSet), depth + 1);
    case 'IFCMATERIALPROFILESET':
      return Refs(l.MaterialProfiles).flatMap((m) => MaterialNames(m, depth + 1));
    case 'IFCMATERIALCONSTITUENTSET':
      return Refs(l.MaterialConstituents).flatMap((m) => MaterialNames(m, depth + 1));
    default:
      return name ? [name] : [];
  }
}
for (const r of IdsOf(W.IFCRELASSOCIATESMATERIAL)) {
  const l = Line(r);
  const names = [...new Set(MaterialNames(Ref(l.RelatingMaterial)))];
  for (const e of Refs(l.RelatedObjects)) for (const n of names) Push(materials, e, n);
}

// "pset:<Set>.<Property>" pairs of a property set or element quantity.
function PropertyPairs(id) {
  const l = Line(id);
  if (!l) return [];
  const set = Text(l.Name) ?? TypeName(id);
  const pairs = [];
  for (const p of Refs(l.HasProperties ?? l.Quantities)) {
    const q = Line(p);
    if (!q || !q.Name) continue;
    let v = null;
    if (q.NominalValue !== undefined) v = Text(q.NominalValue);
    else if (q.EnumerationValues !== undefined) v = Text(q.EnumerationValues);
    else if (q.ListValues !== undefined) v = Text(q.ListValues);
    else if (q.UpperBoundValue !== undefined || q.LowerBoundValue !== undefined)
      v = [Text(q.LowerBoundValue), Text(q.UpperBoundValue)].map((x) => x ?? '').join(' .. ');
    else {  // a quantity: its one measure attribute
      for (const k of ['LengthValue', 'AreaValue', 'VolumeValue', 'CountValue', 'WeightValue', 'TimeValue'])
        if (q[k] !== undefined) v = Text(q[k]);
    }
    if (v !== null) pairs.push([`pset:${set}.${Text(q.Name)}`, v]);
  }
  return pairs;
}
for (const r of IdsOf(W.IFCRELDEFINESBYPROPERTIES)) {
  const l = Line(r);
  // IFC4: the definition may be a set of property sets.
  let defs = Refs(l.RelatingPropertyDefinition);
  if (defs.length === 1 && Line(defs[0]) && Line(defs[0]).PropertyDefinitions)
    defs = Refs(Line(defs[0]).PropertyDefinitions);
  const pairs = defs.flatMap(PropertyPairs);
  for (const e of Refs(l.RelatedObjects)) for (const p of pairs) Push(psets, e, p);
}

// The spatial element and storey of an element: containment first, then up the aggregation.
function StoreyOf(id) {
  for (let at = id, n = 0; at && n < 64; ++n) {
    if (TypeName(at) === 'IFCBUILDINGSTOREY') return at;
    at = container.get(at) ?? aggregate.get(at) ?? (voids.has(at) ? voids.get(at) : null);
  }
  return null;
}

const SPATIAL = new Set(['IFCSPACE', 'IFCOPENINGELEMENT', 'IFCOPENINGSTANDARDCASE', 'IFCSITE', 'IFCBUILDING',
                         'IFCBUILDINGSTOREY', 'IFCSPATIALZONE', 'IFCVOIDINGFEATURE', 'IFCFACILITY',
                         'IFCFACILITYPART', 'IFCBRIDGE', 'IFCBRIDGEPART', 'IFCROAD', 'IFCROADPART',
                         'IFCRAILWAY', 'IFCRAILWAYPART', 'IFCMARINEFACILITY', 'IFCMARINEPART',
                         'IFCEXTERNALSPATIALELEMENT', 'IFCSPATIALELEMENT', 'IFCSPATIALSTRUCTURE',
                         'IFCSPATIALSTRUCTUREELEMENT', 'IFCANNOTATION', 'IFCGRID', 'IFCVIRTUALELEMENT']);

// The IFC type as the schema spells it ("IfcWallStandardCase").
function IfcTypeName(id) { return api.GetNameFromTypeCode(api.GetLineType(model, id)); }

function Attributes(id, ifcType) {
  const l = Line(id);
  const a = [];
  const gid = GlobalId(id);
  a.push(['ifc_global_id', gid ?? '']);
  a.push(['ifc_type', ifcType]);
  const name = l ? Text(l.Name) : null;
  if (name !== null) a.push(['ifc_name', name]);
  a.push(['ifc_schema', schema]);
  const upper = ifcType.toUpperCase();
  if (SPATIAL.has(upper)) a.push(['ifc_spatial', 'true']);
  const storey = StoreyOf(id);
  if (storey !== null && storey !== id) {
    const s = Text(Line(storey)?.Name);
    if (s !== null) a.push(['ifc_storey', s]);
  }
  if (container.has(id)) a.push(['ifc_container', GlobalId(container.get(id)) ?? '']);
  if (aggregate.has(id)) a.push(['ifc_aggregate', GlobalId(aggregate.get(id)) ?? '']);
  if (voids.has(id)) a.push(['ifc_voids', GlobalId(voids.get(id)) ?? '']);
  if (fills.has(id)) {
    const host = voids.get(fills.get(id));
    if (host !== undefined) a.push(['ifc_fills', GlobalId(host) ?? '']);
  }
  let mats = materials.get(id);
  if (!mats && typeOf.has(id)) mats = materials.get(typeOf.get(id));
  for (const m of mats ?? []) a.push(['ifc_material', m]);
  const own = psets.get(id) ?? [];
  const seen = new Set(own.map((p) => p[0]));
  const fromType = [];
  if (typeOf.has(id)) {
    const t = Line(typeOf.get(id));
    for (const ps of Refs(t?.HasPropertySets)) for (const p of PropertyPairs(ps)) if (!seen.has(p[0])) fromType.push(p);
  }
  for (const p of own) a.push(p);
  for (const p of fromType) a.push(p);
  return a;
}

// ---- geometry ---------------------------------------------------------------------------------------
// IfcMapConversion (IFC4 and later) as x' = s (a x - b y) + E, y' = s (b x + a y) + N, z' = s z + H, all in
// metres, or null. Geometry reaches here in metres, E, N, H are in the map unit (the CRS's MapUnit, else the
// project's length unit). Scale: the files disagree whether it includes the unit conversion
// (buildingSMART's geographic-referencing.ifc, in millimetres, omits it): the units are always converted,
// and a Scale equal to that conversion is not applied a second time.
function MapConversion() {
  if (!W.IFCMAPCONVERSION) return null;
  const ids = IdsOf(W.IFCMAPCONVERSION);
  if (ids.length === 0) return null;
  const l = Line(ids[0]);
  const num = (v, d) => {
    const t = Text(v);
    return t === null ? d : Number(t);
  };
  const unitScale = LengthUnitScale();  // metres per project length unit
  let mapUnit = unitScale;
  const crs = Line(Ref(l.TargetCRS));
  if (crs && crs.MapUnit) mapUnit = NamedUnitScale(Ref(crs.MapUnit)) ?? unitScale;
  let ax = num(l.XAxisAbscissa, 1), ay = num(l.XAxisOrdinate, 0);
  const norm = Math.hypot(ax, ay) || 1;
  ax /= norm;
  ay /= norm;
  let s = num(l.Scale, 1);
  const conversion = unitScale / mapUnit;
  if (conversion !== 1 && Math.abs(s / conversion - 1) < 1e-6) s = 1;
  return { s, a: ax, b: ay, E: num(l.Eastings, 0) * mapUnit, N: num(l.Northings, 0) * mapUnit,
           H: num(l.OrthogonalHeight, 0) * mapUnit };
}
const PREFIX = { EXA: 1e18, PETA: 1e15, TERA: 1e12, GIGA: 1e9, MEGA: 1e6, KILO: 1e3, HECTO: 1e2, DECA: 1e1,
                 DECI: 1e-1, CENTI: 1e-2, MILLI: 1e-3, MICRO: 1e-6, NANO: 1e-9, PICO: 1e-12, FEMTO: 1e-15,
                 ATTO: 1e-18 };
function NamedUnitScale(id, depth = 0) {
  const u = Line(id);
  if (!u || depth > 4) return null;
  if (TypeName(id) === 'IFCSIUNIT') return u.Prefix ? (PREFIX[Text(u.Prefix)] ?? 1) : 1;
  if (u.ConversionFactor) {
    const f = Line(Ref(u.ConversionFactor));
    const v = f ? Number(Text(f.ValueComponent)) : NaN;
    const inner = f ? NamedUnitScale(Ref(f.UnitComponent), depth + 1) : null;
    if (Number.isFinite(v) && inner !== null) return v * inner;
  }
  return null;
}
function LengthUnitScale() {
  for (const ua of IdsOf(W.IFCUNITASSIGNMENT)) {
    for (const u of Refs(Line(ua).Units)) {
      const l = Line(u);
      if (l && l.UnitType && Text(l.UnitType) === 'LENGTHUNIT') return NamedUnitScale(u) ?? 1;
    }
  }
  return 1;
}
const mapConversion = MapConversion();

// One product's placed geometries as one mesh in the model's frame. Within a geometry, vertices with the
// same position (web-ifc repeats them per face, with their normals) are welded, by the bits of their local
// float32 coordinates, so that equal positions stay equal after the transform.
let slots = new Int32Array(1 << 16);
function ProductMesh(flat) {
  const positions = [];
  const triangles = [];
  const mc = mapConversion;
  for (let g = 0; g < flat.geometries.size(); ++g) {
    const placed = flat.geometries.get(g);
    const geometry = api.GetGeometry(model, placed.geometryExpressID);
    const v = api.GetVertexArray(geometry.GetVertexData(), geometry.GetVertexDataSize());
    const t = api.GetIndexArray(geometry.GetIndexData(), geometry.GetIndexDataSize());
    const bits = new Uint32Array(v.buffer, v.byteOffset, v.length);
    const m = placed.flatTransformation;  // column-major 4x4, to web-ifc's Y-up frame
    const n = v.length / 6;
    let size = 1;
    while (size < 2 * n) size *= 2;
    if (slots.length < size) slots = new Int32Array(size);
    slots.fill(-1, 0, size);
    const first = new Int32Array(n);  // the vertex each vertex is welded to
    const local = new Uint32Array(n);
    for (let k = 0; k < n; ++k) {
      const i = 6 * k;
      let h = (Math.imul(bits[i], 73856093) ^ Math.imul(bits[i + 1], 19349663) ^ Math.imul(bits[i + 2], 83492791)) &
              (size - 1);
      for (;;) {
        const j = slots[h];
        if (j < 0) {
          slots[h] = k;
          first[k] = k;
          break;
        }
        if (bits[6 * j] === bits[i] && bits[6 * j + 1] === bits[i + 1] && bits[6 * j + 2] === bits[i + 2]) {
          first[k] = j;
          break;
        }
        h = (h + 1) & (size - 1);
      }
      if (first[k] !== k) {
        local[k] = local[first[k]];
        continue;
      }
      const x = v[i], y = v[i + 1], z = v[i + 2];
      const X = m[0] * x + m[4] * y + m[8] * z + m[12];
      const Y = m[1] * x + m[5] * y + m[9] * z + m[13];
      const Z = m[2] * x + m[6] * y + m[10] * z + m[14];
      let px = X, py = -Z, pz = Y;  // web-ifc's Y up back to the model's Z up
      if (mc) {
        const qx = mc.s * (mc.a * px - mc.b * py) + mc.E;
        const qy = mc.s * (mc.b * px + mc.a * py) + mc.N;
        px = qx;
        py = qy;
        pz = mc.s * pz + mc.H;
      }
      local[k] = positions.length / 3;
      positions.push(px, py, pz);
    }
    for (let i = 0; i + 2 < t.length; i += 3) {
      if (t[i] >= n || t[i + 1] >= n || t[i + 2] >= n) continue;
      const a = local[t[i]], b = local[t[i + 1]], c = local[t[i + 2]];
      if (a === b || b === c || a === c) continue;  // degenerate after welding
      triangles.push(a, b, c);
    }
    geometry.delete();
  }
  return { vertices: Float64Array.from(positions), triangles: Uint32Array.from(triangles) };
}

// Whether a product's shape has a body (not only an axis, footprint or annotation).
function HasBody(id) {
  const l = Line(id);
  const shape = l ? Line(Ref(l.Representation)) : null;
  if (!shape) return false;
  for (const r of Refs(shape.Representations)) {
    const rep = Line(r);
    const ident = rep ? (Text(rep.RepresentationIdentifier) ?? '') : '';
    const kind = rep ? (Text(rep.RepresentationType) ?? '') : '';
    if (/^(Body|Facetation|Mesh|Body-Fallback)$/i.test(ident)) return true;
    if (ident === '' && !/Curve|Annotation|Point/i.test(kind)) return true;
  }
  return false;
}

const emitted = new Set();
const failedIds = new Set();  // reported once, whichever way web-ifc failed them
let failed = 0;
function Emit(flat) {
  const id = flat.expressID;
  if (emitted.has(id)) return;
  const type = IfcTypeName(id);
  let mesh;
  try {
    mesh = ProductMesh(flat);
  } catch (e) {
    ++failed;
    failedIds.add(id);
    out.warning(`#${id} ${type} ${GlobalId(id) ?? ''}: web-ifc geometry failed: ${e.message ?? e}`);
    return;
  }
  if (mesh.triangles.length === 0) return;  // reported below, if it has a body
  emitted.add(id);
  const attributes = Attributes(id, type);
  const name = attributes.find((a) => a[0] === 'ifc_name')?.[1] || `${type} ${GlobalId(id) ?? '#' + id}`;
  out.object(name, attributes, mesh.vertices, mesh.triangles);
}

api.StreamAllMeshes(model, (flat) => Emit(flat));
// web-ifc leaves spaces and openings out of StreamAllMeshes: they are kept here, marked ifc_spatial.
const products = IdsOf(W.IFCPRODUCT);
const rest = products.filter((id) => !emitted.has(id) && !failedIds.has(id) && HasBody(id));
for (const id of rest) {
  let flat = null;
  try {
    flat = api.GetFlatMesh(model, id);
  } catch (e) {
    ++failed;
    out.warning(`#${id} ${IfcTypeName(id)} ${GlobalId(id) ?? ''}: web-ifc geometry failed: ${e.message ?? e}`);
    continue;
  }
  Emit(flat);
  try {
    flat.delete();
  } catch (e) {
    // a mesh web-ifc owns
  }
  if (!emitted.has(id) && !failedIds.has(id)) {
    ++failed;
    out.warning(`#${id} ${IfcTypeName(id)} ${GlobalId(id) ?? ''}: has a body representation but web-ifc ` +
                'made no geometry for it; left out');
  }
}
if (failed > 0)
  out.warning(`${failed} of ${emitted.size + failed} products with a body representation have no geometry`);
api.CloseModel(model);
out.end();
