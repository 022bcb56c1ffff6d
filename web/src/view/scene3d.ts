// The 3D view: the liver as it streams (smooth shading, normals recomputed each
// frame, coloured by displacement from rest), the instruments as cylinders from
// the tip to the trocar, the trocars, the vertices each instrument holds as
// cyan points, a force arrow per instrument (10 mm per N, as in the recordings'
// Foxglove scene), an orbit camera and a laparoscope
// camera looking from a camera port between the trocars.
import * as THREE from "three";
import { OrbitControls } from "three/examples/jsm/controls/OrbitControls.js";
import type { SceneDescription } from "../gen/laparo/v1/scene_pb";
import type { InstrumentState } from "../gen/laparo/v1/frame_pb";
import { vertexNormals } from "./normals";

/** Liver tissue at rest, and where displacement takes it (at DISPLACEMENT_FULL_M; lighter, still liver-red). */
const LIVER = new THREE.Color(0x9c3d2c);
const DISPLACED = new THREE.Color(0xe07a50);
/** Displacement drawn in the full highlight colour, m: the sag under gravity plus a firm press,
 * for a liver of the default scene's size (REFERENCE_RADIUS_M); scaled with the scene's. */
const DISPLACEMENT_FULL_M = 0.02;
/** Bounding-sphere radius of the default scene's liver (0.19 m across), m. A scene is
 * assumed to hold a liver of about that size in whatever unit it is written in (the
 * `sofa-liver` scene keeps SOFA's, ~6.5 across): the cameras' near and far planes and
 * the displacement colours scale with its radius. The readouts in mm (max
 * displacement, surface change) assume metres. */
const REFERENCE_RADIUS_M = 0.1;
/** Held vertices: drawn as cyan points of this many pixels, over the surface. */
const HELD = new THREE.Color(0x33e0ff);
const HELD_POINT_PX = 7;
/** Force arrows: 10 mm per newton. */
const ARROW_M_PER_N = 0.01;

interface InstrumentView {
  shaft: THREE.Mesh;
  trocar: THREE.Mesh;
  arrow: THREE.ArrowHelper;
  trocarAt: THREE.Vector3;
  /** The held vertices (surface vertex numbers; room for the whole surface). */
  held: Uint32Array;
  heldCount: number;
  /** Their points, placed on the surface as drawn. */
  heldPoints: THREE.Points;
}

/** Frees the GPU buffers and programs of `root` and everything under it: each
 * geometry and material. (The arrows' line and cone geometries are shared by
 * every arrow; one still drawn uploads them again.) */
function release(root: THREE.Object3D): void {
  root.traverse((o) => {
    const m = o as THREE.Object3D & { geometry?: THREE.BufferGeometry; material?: THREE.Material | THREE.Material[] };
    m.geometry?.dispose();
    for (const material of [m.material ?? []].flat()) material.dispose();
  });
}

export class SceneView {
  readonly renderer: THREE.WebGLRenderer;
  readonly scene = new THREE.Scene();
  readonly orbit: THREE.PerspectiveCamera;
  readonly scope: THREE.PerspectiveCamera;
  readonly controls: OrbitControls;
  useScope = false;
  /** Largest displacement of any surface vertex from rest in the last frame, m. */
  maxDisplacement = 0;
  /** Largest distance of any surface vertex from where the first frame shown
   * had it, m: what the instruments moved since the view opened (the sag under
   * gravity is in the first frame already). */
  maxChange = 0;
  /** Frames drawn (for the tests and the measurements). */
  drawn = 0;
  private liver: THREE.Mesh | null = null;
  private rest: Float32Array = new Float32Array();
  private first: Float32Array | null = null;
  private instruments = new Map<string, InstrumentView>();
  private triangles: Uint32Array = new Uint32Array();
  private center = new THREE.Vector3();
  /** Displacement drawn in the full highlight colour, in the scene's unit. */
  private displacementFull = DISPLACEMENT_FULL_M;
  private dirty = true;
  // Scratch vectors of setInstrument: nothing is allocated per frame.
  private readonly tip = new THREE.Vector3();
  private readonly mid = new THREE.Vector3();
  private readonly dir = new THREE.Vector3();
  private static readonly UP = new THREE.Vector3(0, 1, 0);
  private readonly sizes = new ResizeObserver(() => this.resize());

  constructor(readonly container: HTMLElement) {
    this.renderer = new THREE.WebGLRenderer({ antialias: true });
    this.renderer.setPixelRatio(Math.min(window.devicePixelRatio, 2));
    this.renderer.setClearColor(0x101418);
    container.append(this.renderer.domElement);
    this.orbit = new THREE.PerspectiveCamera(40, 1, 0.001, 10);
    this.scope = new THREE.PerspectiveCamera(70, 1, 0.001, 10);
    this.controls = new OrbitControls(this.orbit, this.renderer.domElement);
    this.controls.addEventListener("change", () => (this.dirty = true));
    this.scene.add(new THREE.HemisphereLight(0xffffff, 0x404050, 1.6));
    const key = new THREE.DirectionalLight(0xffffff, 1.6);
    key.position.set(0.3, 0.5, 0.6);
    this.scene.add(key);
    this.sizes.observe(container);
    this.resize();
  }

  resize(): void {
    const w = Math.max(1, this.container.clientWidth);
    const h = Math.max(1, this.container.clientHeight);
    this.renderer.setSize(w, h, false);
    for (const c of [this.orbit, this.scope]) {
      c.aspect = w / h;
      c.updateProjectionMatrix();
    }
    this.dirty = true;
  }

  /** Builds the liver, instruments and trocars of a scene; frames the camera. */
  setScene(desc: SceneDescription): void {
    // A reconnect sets the scene again: what the last one built is freed, not
    // left to the GPU.
    const old: THREE.Object3D[] = this.liver ? [this.liver] : [];
    for (const v of this.instruments.values()) old.push(v.shaft, v.trocar, v.arrow, v.heldPoints);
    for (const o of old) {
      this.scene.remove(o);
      release(o);
    }
    this.liver = null;
    this.instruments.clear();
    const surface = desc.restSurface;
    this.rest = Float32Array.from(surface?.positions ?? []);
    this.first = null;
    this.maxChange = 0;
    const geometry = new THREE.BufferGeometry();
    geometry.setAttribute("position", new THREE.BufferAttribute(this.rest.slice(), 3).setUsage(THREE.DynamicDrawUsage));
    const colors = new Float32Array(this.rest.length);
    for (let i = 0; i < colors.length; i += 3) LIVER.toArray(colors, i);
    geometry.setAttribute("color", new THREE.BufferAttribute(colors, 3).setUsage(THREE.DynamicDrawUsage));
    this.triangles = Uint32Array.from(surface?.triangles ?? []);
    geometry.setIndex(new THREE.BufferAttribute(this.triangles, 1));
    const normals = new Float32Array(this.rest.length);
    vertexNormals(this.rest, this.triangles, normals);
    geometry.setAttribute("normal", new THREE.BufferAttribute(normals, 3).setUsage(THREE.DynamicDrawUsage));
    geometry.computeBoundingSphere();
    this.liver = new THREE.Mesh(
      geometry,
      new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.55, metalness: 0.05, side: THREE.DoubleSide }),
    );
    this.scene.add(this.liver);
    const sphere = geometry.boundingSphere ?? new THREE.Sphere(new THREE.Vector3(), 0.1);
    this.center.copy(sphere.center);
    const r = Math.max(sphere.radius, 0.01);
    // The default liver's 0.001 and 10 m, in proportion: a scene of another size
    // (or unit) would fall beyond the far plane, or through the near one.
    for (const camera of [this.orbit, this.scope]) {
      camera.near = r / 100;
      camera.far = r * 100;
      camera.updateProjectionMatrix();
    }
    this.displacementFull = (DISPLACEMENT_FULL_M * r) / REFERENCE_RADIUS_M;
    this.orbit.position.set(this.center.x + 0.4 * r, this.center.y + 1.2 * r, this.center.z + 3.2 * r);
    this.controls.target.copy(this.center);
    this.controls.update();
    const trocars: THREE.Vector3[] = [];
    for (const d of desc.instruments) {
      const at = new THREE.Vector3(d.trocar?.x ?? 0, d.trocar?.y ?? 0, d.trocar?.z ?? 0);
      trocars.push(at);
      const shaft = new THREE.Mesh(
        new THREE.CylinderGeometry(d.radiusM, d.radiusM, 1, 16),
        new THREE.MeshStandardMaterial({ color: 0xc9d1d9, metalness: 0.7, roughness: 0.3 }),
      );
      shaft.visible = false;
      const trocar = new THREE.Mesh(
        new THREE.TorusGeometry(d.radiusM * 2.2, d.radiusM * 0.6, 8, 24),
        new THREE.MeshStandardMaterial({ color: 0x4a90d9 }),
      );
      trocar.position.copy(at);
      trocar.lookAt(this.center);
      const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 1, 0), at, 0.01, 0x33ff66, 0.008, 0.005);
      arrow.visible = false;
      const vertices = this.rest.length / 3;
      const heldGeometry = new THREE.BufferGeometry();
      heldGeometry.setAttribute("position", new THREE.BufferAttribute(new Float32Array(3 * vertices), 3).setUsage(THREE.DynamicDrawUsage));
      heldGeometry.setDrawRange(0, 0);
      const heldPoints = new THREE.Points(
        heldGeometry,
        new THREE.PointsMaterial({ color: HELD, size: HELD_POINT_PX, sizeAttenuation: false, depthTest: false }),
      );
      heldPoints.frustumCulled = false;
      heldPoints.renderOrder = 1;
      this.scene.add(shaft, trocar, arrow, heldPoints);
      this.instruments.set(d.name, { shaft, trocar, arrow, trocarAt: at, held: new Uint32Array(vertices), heldCount: 0, heldPoints });
    }
    // The laparoscope's port: between the trocars, a little above, looking at the liver.
    const port = trocars.length
      ? trocars.reduce((a, b) => a.clone().add(b)).multiplyScalar(1 / trocars.length).add(new THREE.Vector3(0, 0.03, 0))
      : this.center.clone().add(new THREE.Vector3(0, 0.05, 3 * r));
    this.scope.position.copy(port);
    this.scope.lookAt(this.center);
    this.dirty = true;
  }

  /** The deformed surface: positions in the rest surface's vertex order. */
  setSurface(positions: ArrayLike<number>): void {
    if (!this.liver || positions.length !== this.rest.length) return;
    const geometry = this.liver.geometry;
    const pos = geometry.getAttribute("position") as THREE.BufferAttribute;
    const col = geometry.getAttribute("color") as THREE.BufferAttribute;
    const p = pos.array as Float32Array;
    const c = col.array as Float32Array;
    let max = 0;
    let change = 0;
    const first = (this.first ??= Float32Array.from(positions));
    for (let i = 0; i < p.length; i += 3) {
      const x = positions[i], y = positions[i + 1], z = positions[i + 2];
      p[i] = x;
      p[i + 1] = y;
      p[i + 2] = z;
      const dx = x - this.rest[i], dy = y - this.rest[i + 1], dz = z - this.rest[i + 2];
      const d = Math.sqrt(dx * dx + dy * dy + dz * dz);
      if (d > max) max = d;
      const cx = x - first[i], cy = y - first[i + 1], cz = z - first[i + 2];
      change = Math.max(change, cx * cx + cy * cy + cz * cz);
      const t = Math.min(1, d / this.displacementFull);
      c[i] = LIVER.r + (DISPLACED.r - LIVER.r) * t;
      c[i + 1] = LIVER.g + (DISPLACED.g - LIVER.g) * t;
      c[i + 2] = LIVER.b + (DISPLACED.b - LIVER.b) * t;
    }
    this.maxDisplacement = max;
    this.maxChange = Math.sqrt(change);
    const normal = geometry.getAttribute("normal") as THREE.BufferAttribute;
    vertexNormals(p, this.triangles, normal.array as Float32Array);
    pos.needsUpdate = true;
    col.needsUpdate = true;
    normal.needsUpdate = true;
    this.dirty = true;
  }

  /** An instrument's shaft (tip to trocar) and force arrow. */
  setInstrument(s: InstrumentState): void {
    const v = this.instruments.get(s.instrument);
    if (!v) return;
    // Vertex numbers beyond the surface (a scene that changed under the view) are left out.
    let count = 0;
    for (const i of s.heldSurfaceVertices) {
      if (i < v.held.length && count < v.held.length) v.held[count++] = i;
    }
    v.heldCount = count;
    const tip = s.pose?.tip;
    if (!tip) {
      v.shaft.visible = false;
      v.arrow.visible = false;
      this.dirty = true;
      return;
    }
    const a = this.tip.set(tip.x, tip.y, tip.z);
    // From the tip to the trocar, as the instrument passes through it.
    const end = v.trocarAt;
    const mid = this.mid.copy(a).add(end).multiplyScalar(0.5);
    const dir = this.dir.copy(end).sub(a);
    const len = dir.length();
    v.shaft.position.copy(mid);
    v.shaft.scale.set(1, Math.max(len, 1e-4), 1);
    v.shaft.quaternion.setFromUnitVectors(SceneView.UP, dir.normalize());
    v.shaft.visible = true;
    const f = s.force?.force;
    const magnitude = s.force?.magnitudeN ?? 0;
    if (f && magnitude > 1e-6) {
      v.arrow.position.copy(a);
      v.arrow.setDirection(this.dir.set(f.x, f.y, f.z).normalize());
      const l = Math.max(0.004, magnitude * ARROW_M_PER_N);
      v.arrow.setLength(l, Math.min(0.008, 0.4 * l), Math.min(0.005, 0.25 * l));
      v.arrow.visible = true;
    } else {
      v.arrow.visible = false;
    }
    this.dirty = true;
  }

  /** Draws if anything changed; true when it drew. */
  draw(): boolean {
    if (!this.dirty) return false;
    this.dirty = false;
    this.placeHeld();
    this.renderer.render(this.scene, this.useScope ? this.scope : this.orbit);
    this.drawn++;
    return true;
  }

  /** Held vertices drawn, per instrument (for the browser tests). */
  heldDrawn(instrument: string): number {
    return this.instruments.get(instrument)?.heldPoints.geometry.drawRange.count ?? 0;
  }

  /** Puts each instrument's held points where the surface as drawn has those vertices. */
  private placeHeld(): void {
    if (!this.liver) return;
    const p = (this.liver.geometry.getAttribute("position") as THREE.BufferAttribute).array as Float32Array;
    for (const v of this.instruments.values()) {
      const attr = v.heldPoints.geometry.getAttribute("position") as THREE.BufferAttribute;
      const out = attr.array as Float32Array;
      for (let k = 0; k < v.heldCount; k++) {
        const i = 3 * v.held[k];
        out[3 * k] = p[i];
        out[3 * k + 1] = p[i + 1];
        out[3 * k + 2] = p[i + 2];
      }
      v.heldPoints.geometry.setDrawRange(0, v.heldCount);
      if (v.heldCount > 0) {
        attr.clearUpdateRanges();
        attr.addUpdateRange(0, 3 * v.heldCount);
        attr.needsUpdate = true;
      }
    }
  }

  redraw(): void {
    this.dirty = true;
  }

  /** Frees what the view holds on the GPU, its WebGL context included: a
   * browser keeps about 16 contexts alive, and one only disposed stays until
   * garbage collection, so switching views a few dozen times made chromium
   * drop the oldest ("Too many active WebGL contexts"). */
  dispose(): void {
    this.sizes.disconnect();
    release(this.scene);
    this.controls.dispose();
    this.renderer.dispose();
    this.renderer.forceContextLoss();
    this.renderer.domElement.remove();
  }
}
