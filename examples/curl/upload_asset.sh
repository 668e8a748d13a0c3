#!/bin/sh
# See README.md ("Meshes from files"). DRAPE is the server (default http://127.0.0.1:8080).
set -eu
DRAPE="${DRAPE:-http://127.0.0.1:8080}"
# POST /assets: upload a mesh file (.obj or .glb) and print the asset (its id, vertex and
# triangle counts). Usage: upload_asset.sh MESH.obj|MESH.glb
case "$1" in
  *.glb|*.GLB) TYPE=model/gltf-binary ;;
  *) TYPE=model/obj ;;
esac
curl -sS --fail-with-body -H "Content-Type: $TYPE" --data-binary "@$1" "$DRAPE/assets"
echo
