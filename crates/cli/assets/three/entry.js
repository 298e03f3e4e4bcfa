// The part of three.js the result viewer uses, bundled once into three-bundle.min.js (see
// vendor.sh): the core and OrbitControls, as the global ARMATURE_THREE.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';

globalThis.ARMATURE_THREE = { THREE, OrbitControls };
