#!/bin/sh
# Blender 3.4 cloth baseline on the shipped garments (see docs/garments.md).
# Runs one case at a time (timings are wall and CPU seconds; the machine's load is recorded in
# each JSON). Usage: sh benches/blender_baseline.sh [CASE...]   (default: all cases)
# Cases: skirt skirt-step skirt-physical skirt8k skirt8k-physical skirt-draped dress skirt-sphere
#        skirt-draped-thin dress-thin (collision margins 2 mm instead of Blender's 15 + 20 mm)
#        skirt-2k skirt-32k (the circle skirt remeshed coarser and finer: resolution dependence)
#        skirt-table (the circle skirt raised 0.15 m, unpinned, dropped on meshes/table.obj)
#        dress-kick (the draped dress on the kicking mannequin, ../shared/meshes/obj/bodies/kick/,
#        its first 10 frames at 25 fps, self-collision on at 3 mm, 2 mm margins, cotton's
#        0.15 kg/m²; also writes the cloth's frames as a PC2 for examples/crossings)
set -e
cd "$(dirname "$0")/.."
OUT=benches/blender_results
mkdir -p "$OUT"
blender_cloth() {
    env -u PYTHONPATH -u PYTHONHOME PATH=/usr/sbin:/usr/bin:/sbin:/bin \
        blender -b --factory-startup --python-exit-code 1 --python benches/blender_cloth.py -- "$@"
}
WAIST=-0.2,0.999,-0.2,0.2,1.001,0.2
run() {
    case "$1" in
    skirt) blender_cloth meshes/garments/circle_skirt.obj --pin-box $WAIST --frames 30 --out $OUT/circle_skirt.json ;;
    skirt-step) blender_cloth meshes/garments/circle_skirt.obj --pin-box $WAIST --frames 30 --step --snapshots 0 --out $OUT/circle_skirt_step.json ;;
    skirt-physical) blender_cloth meshes/garments/circle_skirt.obj --pin-box $WAIST --frames 30 --mass-per-area 0.2 --out $OUT/circle_skirt_0.2kgm2.json ;;
    skirt8k) blender_cloth meshes/garments/skirt8K.obj --pin-box $WAIST --frames 30 --out $OUT/skirt8K.json ;;
    skirt8k-physical) blender_cloth meshes/garments/skirt8K.obj --pin-box $WAIST --frames 30 --mass-per-area 0.2 --out $OUT/skirt8K_0.2kgm2.json ;;
    skirt-draped) blender_cloth meshes/garments/skirt_draped.obj --pin-box -0.25,0.102,-0.25,0.25,0.12,0.25 --collider-obj meshes/garments/mannequin.obj --frames 30 --out $OUT/skirt_draped_on_mannequin.json ;;
    skirt-sphere) blender_cloth meshes/garments/circle_skirt.obj --collider-sphere 0,0.7,0,0.25 --frames 30 --out $OUT/circle_skirt_on_sphere.json ;;
    skirt-draped-thin) blender_cloth meshes/garments/skirt_draped.obj --pin-box -0.25,0.102,-0.25,0.25,0.12,0.25 --collider-obj meshes/garments/mannequin.obj --collision-distance 0.002 --collider-thickness 0.002 --frames 30 --out $OUT/skirt_draped_on_mannequin_2mm.json ;;
    dress-thin) blender_cloth meshes/garments/dress_draped.obj --collider-obj meshes/garments/mannequin.obj --collision-distance 0.002 --collider-thickness 0.002 --frames 30 --out $OUT/dress_on_mannequin_2mm.json ;;
    skirt-2k) python3 scripts/make_skirt.py --vertices 2000 --out $OUT/circle_skirt_2k.obj
        blender_cloth $OUT/circle_skirt_2k.obj --pin-box $WAIST --frames 30 --out $OUT/circle_skirt_2k.json ;;
    skirt-32k) python3 scripts/make_skirt.py --vertices 32000 --out $OUT/circle_skirt_32k.obj
        blender_cloth $OUT/circle_skirt_32k.obj --pin-box $WAIST --frames 10 --out $OUT/circle_skirt_32k.json ;;
    skirt-table) python3 scripts/place_obj.py meshes/garments/circle_skirt.obj $OUT/circle_skirt_raised.obj --translate 0,0.15,0
        blender_cloth $OUT/circle_skirt_raised.obj --collider-obj meshes/table.obj --frames 30 --out $OUT/circle_skirt_on_table.json ;;
    dress-kick) blender_cloth meshes/garments/dress_draped.obj --translate 0,0.75,0 --collider-sequence '../shared/meshes/obj/bodies/kick/shell%d.obj' --fps 25 --frames 10 --self-collision --self-distance 0.003 --collision-distance 0.002 --collider-thickness 0.002 --mass-per-area 0.15 --pc2-out $OUT/dress_kick.pc2 --out $OUT/dress_kick.json ;;
    dress) blender_cloth meshes/garments/dress_draped.obj --collider-obj meshes/garments/mannequin.obj --frames 30 --out $OUT/dress_on_mannequin.json ;;
    *) echo "unknown case $1" >&2; exit 2 ;;
    esac
}
if [ $# -eq 0 ]; then set -- skirt skirt-step skirt-physical skirt8k skirt8k-physical skirt-draped dress skirt-sphere skirt-draped-thin dress-thin skirt-2k skirt-32k skirt-table; fi
for c in "$@"; do run "$c"; done
