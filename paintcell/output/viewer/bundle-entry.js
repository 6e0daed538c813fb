// The three.js pieces the report's film viewer uses (film_view.js), bundled into
// three-film.min.js as the global `PaintcellThree` (see README.md for the build command).
export { Box3, PerspectiveCamera, Raycaster, Scene, Vector2, Vector3, WebGLRenderer } from 'three';
export { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
export { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
