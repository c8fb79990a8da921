#!/usr/bin/env bash
# Measures which velocity-layer settings never settle (the data behind the stability rule in
# docs/parameters.md). For each setting: the paper protocol on a phantom, then idle frames;
# prints the mean skin&fat speed (cells/frame) over the last 50 frames. Settled runs are near 0,
# unstable ones keep moving at about v_max * beta * rho.
# usage: scripts/stability_sweep.sh HPCM_BINARY OUT_DIR [PHANTOM] [FRAMES] > sweep.csv
set -euo pipefail
HPCM=$1 OUT=$2 PHANTOM=${3:-32,32,24} FRAMES=${4:-250}
mkdir -p "$OUT"
echo "mode,gain,alpha,b0,v_max,last50_mean_skin_speed,last50_max_skin_speed"
one() {  # mode gain alpha b0 vmax
  local mode=$1 g=$2 a=$3 b0=$4 vmax=$5 beta rho
  beta=$(awk -v g="$g" 'BEGIN{print (g <= 2 ? g : 2)}')
  rho=$(awk -v g="$g" 'BEGIN{print (g <= 2 ? 1 : g / 2)}')
  local tag="${mode}_g${g}_a${a}_b${b0}_v${vmax}"
  cat > "$OUT/$tag.toml" <<TOML
[dynamics]
mode = "$mode"
alpha = $a
b0 = $b0
v_max = $vmax
beta = $beta
rho = $rho
TOML
  rm -rf "$OUT/$tag"
  "$HPCM" run --phantom "$PHANTOM" --frames "$FRAMES" --no-link-check --params "$OUT/$tag.toml" --out "$OUT/$tag" >/dev/null
  awk -F, -v n="$FRAMES" -v tag="$mode,$g,$a,$b0,$vmax" \
    'NR > 1 && $1 >= n - 50 { s += $10; if ($14 > m) m = $14; k++ } END { printf "%s,%.6g,%.6g\n", tag, s / k, m }' \
    "$OUT/$tag/frames.csv"
}
for g in 0.5 1 1.5 1.75 2 2.25 2.5 3 4; do
  for a in 0 0.5 0.85 0.98 1; do one simple "$g" "$a" 0.025 0.5; done
  for b0 in 0 0.025 0.15 0.5; do one viscoelastic "$g" 0.98 "$b0" 0.5; done
done
for vmax in 0.1 2 10; do
  for g in 1 2 4; do one simple "$g" 0.98 0.025 "$vmax"; one viscoelastic "$g" 0.98 0.025 "$vmax"; done
done
