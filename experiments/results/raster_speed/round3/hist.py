import sys,re,subprocess
from collections import Counter
data=sys.argv[1]
out=subprocess.run(['perf','script','-i',data,'-F','ip,sym,symoff'],capture_output=True,text=True).stdout
fn=Counter(); off=Counter()
for l in out.splitlines():
    m=re.match(r'\s*([0-9a-f]+)\s+(.*)\+0x([0-9a-f]+)$',l.strip())
    if not m: continue
    ip=int(m.group(1),16); o=int(m.group(3),16); start=ip-o
    fn[(start,m.group(2)[:60])]+=1; off[(start,o//32*32)]+=1
tot=sum(fn.values())
for (s,name),n in fn.most_common(6): print(hex(s),name,n,f"{100*n/tot:.1f}%")
top=fn.most_common(1)[0][0][0]
print("hot 32-byte blocks of top fn (offset, samples):")
blocks=sorted(((o,n) for (s,o),n in off.items() if s==top), key=lambda x:-x[1])[:25]
for o,n in sorted(blocks): print(hex(o),n)
