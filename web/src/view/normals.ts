// Smooth vertex normals of a triangle mesh, recomputed in place each frame.
//
// The normal at vertex v is the area-weighted sum of the normals of the
// triangles around it, normalised:
//
//   n_v = Σ_{t ∋ v} (b_t − a_t) × (c_t − a_t)  /  |Σ …|
//
// (the cross product of a triangle's edges is twice its area times its unit
// normal, so larger triangles count more: the smooth shading three.js's
// computeVertexNormals gives, without its per-vertex object accessors). The
// rest surface's triangles are counter-clockwise seen from outside, so n_v
// points out of the liver. A vertex of no triangle, or of only degenerate ones,
// keeps a zero normal.

/** Writes into `normals` (length = positions.length) the vertex normals of the
 * mesh `positions` (x, y, z per vertex), `triangles` (three vertex indices each). */
export function vertexNormals(positions: Float32Array, triangles: Uint32Array, normals: Float32Array): void {
  normals.fill(0);
  for (let t = 0; t < triangles.length; t += 3) {
    const a = 3 * triangles[t], b = 3 * triangles[t + 1], c = 3 * triangles[t + 2];
    const ax = positions[a], ay = positions[a + 1], az = positions[a + 2];
    const ux = positions[b] - ax, uy = positions[b + 1] - ay, uz = positions[b + 2] - az;
    const vx = positions[c] - ax, vy = positions[c + 1] - ay, vz = positions[c + 2] - az;
    const nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
    normals[a] += nx;
    normals[a + 1] += ny;
    normals[a + 2] += nz;
    normals[b] += nx;
    normals[b + 1] += ny;
    normals[b + 2] += nz;
    normals[c] += nx;
    normals[c + 1] += ny;
    normals[c + 2] += nz;
  }
  for (let i = 0; i < normals.length; i += 3) {
    const x = normals[i], y = normals[i + 1], z = normals[i + 2];
    const l = Math.sqrt(x * x + y * y + z * z);
    if (l > 0) {
      normals[i] = x / l;
      normals[i + 1] = y / l;
      normals[i + 2] = z / l;
    }
  }
}
