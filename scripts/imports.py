#!/usr/bin/env python3
"""Import graph of the crate's src/: circles between sibling modules and upward arrows.

Usage: python3 scripts/imports.py [src] [-v] [--edges PREFIX]   (issue 30; no dependency)


A file's references (use statements and inline crate::/super::/self:: paths) are resolved to
the module that *defines* the item (following `pub use` re-exports). An arrow S -> T between
two different modules is lifted to the children of their lowest common ancestor; a circle is
a strongly connected component (size > 1) of such a sibling graph. An upward arrow is a
reference from a module to an item defined in the own file of one of its ancestors.
"""
import os, re, sys, collections
root = sys.argv[1] if len(sys.argv) > 1 else 'src'
verbose = '-v' in sys.argv
mods = {}  # modpath tuple -> file
for d, _, fs in os.walk(root):
    for f in fs:
        if not f.endswith('.rs'): continue
        p = os.path.join(d, f); rel = os.path.relpath(p, root)[:-3].split(os.sep)
        if rel == ['lib']: mp = ()
        elif rel == ['main']: continue
        elif rel[-1] == 'mod': mp = tuple(rel[:-1])
        else: mp = tuple(rel)
        if mp and mp[0] == 'cli': continue  # the binary's modules
        if mp and mp[-1] == 'tests': continue  # test modules
        mods[mp] = p
src = {m: open(p).read() for m, p in mods.items()}
def strip_comments(s):
    s = re.sub(r'//[^\n]*', '', s)
    s = re.sub(r'/\*.*?\*/', '', s, flags=re.S)
    s = re.sub(r'"(\\.|[^"\\])*"', '""', s)
    return s
code = {m: strip_comments(s) for m, s in src.items()}
# strip #[cfg(test)] mod tests { ... } blocks
def strip_tests(s):
    out = ''
    while True:
        m = re.search(r'#\[cfg\(test\)\]\s*mod\s+\w+\s*\{', s)
        if not m: return out + s
        j = m.end() - 1; depth = 0; k = j
        while k < len(s):
            if s[k] == '{': depth += 1
            elif s[k] == '}':
                depth -= 1
                if depth == 0: break
            k += 1
        out += s[:m.start()]; s = s[k+1:]
code = {m: strip_tests(s) for m, s in code.items()}
def expand_use(body):
    body = re.sub(r'\s+', '', body)
    def rec(prefix, s):
        out = []; i = s.find('{')
        if i < 0:
            return [prefix + s]
        head = s[:i]; inner = s[i+1:s.rfind('}')]
        parts = []; depth = 0; cur = ''
        for c in inner:
            if c == '{': depth += 1
            if c == '}': depth -= 1
            if c == ',' and depth == 0: parts.append(cur); cur = ''
            else: cur += c
        if cur: parts.append(cur)
        for p in parts: out += rec(prefix + head, p)
        return out
    return [re.sub(r'as\w+$', '', x) for x in rec('', body)]
def absolute(m, path):
    segs = [s for s in path.split('::') if s]
    if not segs: return None
    if segs[0] in ('crate', '$crate', 'greybox'): return list(segs[1:])
    base = list(m)
    if segs[0] == 'self': return base + segs[1:]
    if segs[0] == 'super':
        while segs and segs[0] == 'super': base = base[:-1]; segs = segs[1:]
        return base + segs
    # a local child module
    if tuple(base + [segs[0]]) in mods: return base + segs
    return None
uses = collections.defaultdict(list)  # module -> list of (abs path list, is_pub_use)
for m, s in code.items():
    for mt in re.finditer(r'(pub(\([^)]*\))?\s+)?use\s+([^;]+);', s):
        for u in expand_use(mt.group(3)):
            a = absolute(m, u)
            if a is not None: uses[m].append((a, bool(mt.group(1))))
    for mt in re.finditer(r'(?<![\w:])((?:\$?crate|super|self)(?:::\w+)+)', s):
        a = absolute(m, mt.group(1))
        if a is not None: uses[m].append((a, False))
# re-exports: (module, name) -> target abs path
reexp = {}
for m in mods:
    for a, pub in uses[m]:
        if pub and a: reexp[(m, a[-1])] = a
    # glob re-exports
for m in mods:
    for a, pub in uses[m]:
        if pub and a and a[-1] == '*': reexp[(m, '*' + '::'.join(a[:-1]))] = a
def defined_in(mp, name):
    pat = r'\b(fn|struct|enum|trait|type|const|static|macro_rules!)\s+' + re.escape(name) + r'\b'
    return re.search(pat, code[mp]) is not None
def resolve(a, depth=0):
    """The module that defines the item at abs path a."""
    k = len(a)
    while k > 0 and tuple(a[:k]) not in mods: k -= 1
    mp = tuple(a[:k]); rest = a[k:]
    if not rest or rest == ['*']: return mp
    name = rest[0]
    if depth < 10 and (mp, name) in reexp and not defined_in(mp, name):
        t = reexp[(mp, name)]
        if t != a: return resolve(t + rest[1:], depth + 1)
    if depth < 10 and not defined_in(mp, name):
        for (mm, key), t in reexp.items():
            if mm == mp and key.startswith('*'):
                r = resolve(t[:-1] + rest, depth + 1)
                if r != mp: return r
    return mp
edges = collections.defaultdict(set)  # (S, T) -> set of names
for m in mods:
    for a, pub in uses[m]:
        if pub: continue
        t = resolve(a)
        if t != m and t in mods: edges[(m, t)].add('::'.join(a))
upward = []; sib = collections.defaultdict(lambda: collections.defaultdict(set))
for (s, t), names in edges.items():
    if s[:len(t)] == t:
        if t != (): upward.append((s, t, names))
        continue
    if t[:len(s)] == s: continue
    i = 0
    while i < min(len(s), len(t)) and s[i] == t[i]: i += 1
    p = s[:i]; sib[p][s[i]].add(t[i])
    sib[p].setdefault(t[i], set())
    sib[(p, s[i], t[i])] = names
def sccs(g):
    idx = {}; low = {}; st = []; on = set(); out = []; c = [0]
    sys.setrecursionlimit(10000)
    def v(n):
        idx[n] = low[n] = c[0]; c[0] += 1; st.append(n); on.add(n)
        for w in g.get(n, ()):
            if w not in idx: v(w); low[n] = min(low[n], low[w])
            elif w in on: low[n] = min(low[n], idx[w])
        if low[n] == idx[n]:
            comp = []
            while True:
                w = st.pop(); on.discard(w); comp.append(w)
                if w == n: break
            if len(comp) > 1: out.append(comp)
    for n in list(g): 
        if n not in idx: v(n)
    return out
circles = []
for p, g in list(sib.items()):
    if not isinstance(g, dict): continue
    for comp in sccs(g):
        circles.append((p, comp))
print(f'modules: {len(mods)}; arrows between modules: {len(edges)}')
print(f'import circles (strongly connected sibling groups): {len(circles)}')
for p, comp in circles:
    print('  in', '::'.join(p) or 'crate', ':', ' <-> '.join(sorted(comp)))
    if verbose:
        for a in comp:
            for b in comp:
                if b in sib[p].get(a, ()):
                    # which files
                    for (s, t), names in edges.items():
                        if len(s) > len(p) and len(t) > len(p) and s[:len(p)] == p and t[:len(p)] == p and s[len(p)] == a and t[len(p)] == b:
                            print('     ', '::'.join(s), '->', '::'.join(t), sorted(names)[:3])
inside = [u for u in upward if u[0][0] == 'pmsm']
print(f'upward arrows (to an item defined in an ancestor\'s own file): {len(upward)}, inside pmsm/: {len(inside)}, outside: {len(upward) - len(inside)}')
for s, t, names in sorted(upward):
    print('  ', '::'.join(s), '->', '::'.join(t) or 'crate', sorted(names)[:4])
if '--edges' in sys.argv:
    pre = tuple(sys.argv[sys.argv.index('--edges') + 1].split('::'))
    for (s, t), names in sorted(edges.items()):
        if s[:len(pre)] == pre and t[:len(pre)] == pre:
            print('E', '::'.join(s[len(pre):]) or '.', '->', '::'.join(t[len(pre):]) or '.', ' '.join(sorted(n.split('::')[-1] for n in names))[:120])
