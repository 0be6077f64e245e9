# A simulated shoot day for the scale test and bench/process_day.sh (sourced).
# simulate_day SETLIGHT N SIZE DIR [DISTINCT [SCENES]]: DIR/setup_001 ..
# setup_N, each a virtual-set capture (3 fisheye views x 7 frames, the three
# probes). DISTINCT captures (default 10; the SCENES in turn, default
# "exterior stage night", each scene's k-th with seed k) are simulated two at
# a time; the other setups are hard-linked
# copies of them (the pipeline keys a job by its setup's paths too, so every
# setup's jobs run). DIR/.day records what was made, so a second call with the
# same arguments and binary reuses it.
simulate_day() {
  local exe=$1 n=$2 size=$3 dir=$4 distinct=${5:-10}
  local scenes
  read -r -a scenes <<<"${6:-exterior stage night}"
  [ "$distinct" -gt "$n" ] && distinct=$n
  local tag
  tag="$n $size $distinct ${scenes[*]} $(sha256sum <"$exe" | cut -c1-16)"
  if [ -f "$dir/.day" ] && [ "$(cat "$dir/.day")" = "$tag" ]; then return 0; fi
  rm -rf "$dir"
  mkdir -p "$dir/.captures"
  local k m=${#scenes[@]}
  for ((k = 0; k < distinct; k++)); do
    printf '%s %s %s\n' "${scenes[k % m]}" "$((1 + k / m))" "$k"
  done | xargs -P 2 -L 1 sh -c '"$0" simulate --size "$1" --scene "$3" --seed "$4" -o "$2/c$5" -q' \
      "$exe" "$size" "$dir/.captures"
  local i
  for ((i = 1; i <= n; i++)); do
    k=$(((i - 1) % distinct))
    [ -f "$dir/.captures/c$k/capture.json" ] || return 1
    cp -al "$dir/.captures/c$k" "$(printf '%s/setup_%03d' "$dir" "$i")"
  done
  echo "$tag" >"$dir/.day"
}
