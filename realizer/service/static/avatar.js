// glTF avatars in the browser viewer (`realizer serve --avatar model.glb`): the server serves
// the file at /avatar.glb and says so in /avatar.json; the viewer loads it with three.js'
// GLTFLoader and drives its ARKit-named morph targets from the `arkit` stream, its head and
// eye bones (if any) from the pose angles. Missing targets are listed once, in a warning.
import { GLTFLoader } from "three/addons/GLTFLoader.js";
import { ARKIT_NAMES } from "/static/fapcodec.js";

const HEAD_BONES = ["head", "Head", "mixamorigHead", "J_Bip_C_Head"];
const LEFT_EYE_BONES = ["leftEye", "LeftEye", "eye_L", "J_Adj_L_FaceEye", "mixamorigLeftEye"];
const RIGHT_EYE_BONES = ["rightEye", "RightEye", "eye_R", "J_Adj_R_FaceEye", "mixamorigRightEye"];

export async function loadAvatar(scene, state, THREE) {
  const info = await (await fetch("/avatar.json")).json();
  if (!info.avatar) return null;
  const gltf = await new GLTFLoader().loadAsync("/avatar.glb");
  const root = gltf.scene;
  const targets = new Map();  // name -> [[mesh, index], ...]
  root.traverse((o) => {
    if (!o.isMesh || !o.morphTargetDictionary) return;
    for (const [name, index] of Object.entries(o.morphTargetDictionary)) {
      if (!targets.has(name)) targets.set(name, []);
      targets.get(name).push([o, index]);
    }
  });
  const find = (names) => names.map((n) => root.getObjectByName(n)).find(Boolean) || null;
  const bones = { head: find(HEAD_BONES), leftEye: find(LEFT_EYE_BONES), rightEye: find(RIGHT_EYE_BONES) };
  const rest = {};
  for (const [k, b] of Object.entries(bones)) if (b) rest[k] = b.quaternion.clone();
  const missing = ARKIT_NAMES.filter((n) => !targets.has(n));
  scene.add(root);
  const avatar = {
    root, missing, bones: Object.fromEntries(Object.entries(bones).map(([k, b]) => [k, b ? b.name : null])),
    frames: 0, weights: null,
    apply(arkit) {
      const weights = arkit.subarray ? arkit.subarray(0, 52) : arkit;
      ARKIT_NAMES.forEach((name, i) => {
        for (const [mesh, index] of targets.get(name) || []) mesh.morphTargetInfluences[index] = weights[i];
      });
      this.weights = Array.from(weights);
      this.frames++;
      state.dirty = true;
    },
    pose(angles) {  // head pitch, yaw, roll, left eye pitch, yaw, right eye pitch, yaw (radians)
      const turn = (bone, key, pitch, yaw, roll) => {
        if (!bone) return;
        const q = new THREE.Quaternion().setFromEuler(new THREE.Euler(pitch, yaw, roll, "YXZ"));
        bone.quaternion.copy(rest[key]).multiply(q);
      };
      turn(bones.head, "head", angles[0], angles[1], -angles[2]);
      turn(bones.leftEye, "leftEye", angles[3], angles[4], 0);
      turn(bones.rightEye, "rightEye", angles[5], angles[6], 0);
    },
  };
  if (missing.length) {
    const text = `avatar: ${missing.length} ARKit morph targets missing (${missing.join(", ")}); the rest animate`;
    state.feedback.push({ kind: "warning", text });
    const li = document.createElement("li"); li.className = "warning"; li.textContent = text;
    document.getElementById("feedback").appendChild(li);
  }
  state.avatar = avatar;
  if (state.layout) state.layout();  // beside the characters
  return avatar;
}
