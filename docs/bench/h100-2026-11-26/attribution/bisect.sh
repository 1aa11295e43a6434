#!/usr/bin/env bash
# GPU attribution of the G->H change: each binary's method times, interleaved, twice.
set -o pipefail
[ -n "$LOCAL" ] || { for f in .gl/*.deb; do dpkg -x $f / ; done; ldconfig; }
cd .devbin; for x in *.xz; do [ -f "${x%.xz}" ] || xz -d -k -T0 "$x"; done; chmod +x dispmap-*; cd ..
B0=$(ls .devbin/dispmap-* | grep -v '\.xz$' | head -1)
if ! $B0 info >/dev/null 2>&1; then export VK_DRIVER_FILES=/usr/local/nvidia/share/vulkan/icd.d/nvidia_icd.json; fi
SIZE=${SIZE:-1920x1080}
order="${BINS:-a6769ce 95096b8 46ef2dd fd30368 8821de8 d5bc8f2}"
rev=$(echo $order | tr ' ' '\n' | tac | tr '\n' ' ')
echo "tag,pass,map,method,steps,method_ms,method_median_ms,total_ms,iterations_warp32" > $OUT/bisect.csv
for pass in 1 2; do
  [ $pass = 2 ] && list=$rev || list=$order
  for c in $list; do
    B=.devbin/dispmap-$c; [ -x $B ] || continue
    extra=""; $B bench --help | grep -q -- '--materials' && extra="$extra --materials off"; $B bench --help | grep -q -- '--forward' && extra="$extra --forward off"
    rm -rf /tmp/b; $B bench --size $SIZE --error-frames 1 --methods ${METHODS:-bump,relief,exact,pyramid,cone} --maps ${MAPS:-rocks,mountains} --steps 150 --sizes none --quiet --out /tmp/b $extra >/tmp/log 2>&1 || { echo "$c failed"; tail -3 /tmp/log; continue; }
    python3 - "$c" "$pass" >> $OUT/bisect.csv <<'PY'
import csv,sys
for r in csv.DictReader(open('/tmp/b/results.csv')):
    if r['sweep']!='methods': continue
    print(','.join([sys.argv[1],sys.argv[2],r['map'],r['method'],r['steps'],r['method_ms'],r['method_median_ms'],r['total_ms'],r['iterations_warp32']]))
PY
  done
done
python3 - <<'PY'
import csv,os,collections
d=collections.defaultdict(list)
for r in csv.DictReader(open(os.environ['OUT']+'/bisect.csv')):
    d[(r['map'],r['method'],r['tag'])].append(float(r['method_ms']))
tags=os.environ.get('BINS','a6769ce 95096b8 46ef2dd fd30368 8821de8 d5bc8f2').split()
keys=sorted({(m,me) for (m,me,t) in d})
print('map method '+' '.join(tags))
for k in keys:
    print(k[0],k[1],' '.join('%.3f/%.3f'%tuple(sorted(d[(k[0],k[1],t)])[:1]+sorted(d[(k[0],k[1],t)])[-1:]) if (k[0],k[1],t) in d else '-' for t in tags))
PY
