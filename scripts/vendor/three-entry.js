export { Scene, Group, Color, Vector3, Quaternion, Matrix4, PerspectiveCamera, OrthographicCamera, WebGLRenderer,
  Mesh, MeshStandardMaterial, MeshBasicMaterial, LineBasicMaterial, LineDashedMaterial, BoxGeometry, SphereGeometry, CylinderGeometry,
  CapsuleGeometry, ConeGeometry, PlaneGeometry, BufferGeometry, Float32BufferAttribute, Line, LineSegments, AmbientLight,
  DirectionalLight, HemisphereLight, GridHelper, AxesHelper, ArrowHelper, DoubleSide, EdgesGeometry, Box3, Sphere } from 'three';
export { OrbitControls } from 'three/addons/controls/OrbitControls.js';
