// web-ifc's own conversion, the baseline of bench/ifc_ingest.sh: open the file and stream every mesh
// (StreamAllMeshes, each placed geometry's vertex and index arrays fetched), as web-ifc's examples do;
// no attributes, no relations, nothing written. Usage: node bench/ifc_webifc_geometry.mjs FILE.ifc
import fs from 'node:fs';
import { createRequire } from 'node:module';

const W = createRequire(new URL('../tools/ifc/', import.meta.url))('web-ifc');
const api = new W.IfcAPI();
await api.Init();
api.SetLogLevel(W.LogLevel.LOG_LEVEL_OFF);
const model = api.OpenModel(fs.readFileSync(process.argv[2]), { COORDINATE_TO_ORIGIN: false });
let meshes = 0, triangles = 0;
api.StreamAllMeshes(model, (flat) => {
  ++meshes;
  for (let g = 0; g < flat.geometries.size(); ++g) {
    const geometry = api.GetGeometry(model, flat.geometries.get(g).geometryExpressID);
    api.GetVertexArray(geometry.GetVertexData(), geometry.GetVertexDataSize());
    triangles += api.GetIndexArray(geometry.GetIndexData(), geometry.GetIndexDataSize()).length / 3;
    geometry.delete();
  }
});
api.CloseModel(model);
console.error(`${meshes} meshes, ${triangles} triangles`);
