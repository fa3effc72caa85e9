"""The include graph between the library's topics, and its two rules.

    python3 scripts/include_graph.py [SOURCE_ROOT]      # check the tree (default: this checkout)
    python3 scripts/include_graph.py --self-test         # check that the checks can fail

A topic is a folder of the library: libflowvid/{src,include/flowvid}/<topic>/
(cloth, flow, gap, metrics, optim, render, rigid, video) and formats/ (the
file formats). A file of one topic including "flowvid/<other>/..." is an
edge topic -> other. The rules:
  1. no cycle between topics (a topic a newcomer reads first must not need
     one read later);
  2. formats/ includes no other topic (formats know nothing of algorithms).
The command-line tool, benches and tests may include anything and are not
part of the graph. Prints the graph; exits 1 naming each broken rule with
the files that make it, 0 otherwise.
"""
import os
import re
import sys
import tempfile

INCLUDE = re.compile(r'^\s*#\s*include\s+"flowvid/([^/"]+)/', re.MULTILINE)
SOURCE_SUFFIXES = (".cpp", ".hpp", ".h", ".cc")


def topic_roots(root):
    """(folder, topic or None) pairs: None means each subfolder is a topic."""
    return [(os.path.join(root, "libflowvid", "src"), None),
            (os.path.join(root, "libflowvid", "include", "flowvid"), None),
            (os.path.join(root, "formats", "src"), "formats"),
            (os.path.join(root, "formats", "include", "flowvid"), "formats")]


def include_edges(root):
    """{(from_topic, to_topic): [files]} for includes across topics."""
    edges = {}
    for folder, fixed_topic in topic_roots(root):
        for directory, _, files in os.walk(folder):
            relative = os.path.relpath(directory, folder)
            topic = fixed_topic or (relative.split(os.sep)[0] if relative != "." else None)
            if topic is None:
                continue  # files directly under src/ (version.cpp) belong to no topic
            for name in files:
                if not name.endswith(SOURCE_SUFFIXES):
                    continue
                path = os.path.join(directory, name)
                with open(path, encoding="utf-8", errors="replace") as f:
                    text = f.read()
                for other in INCLUDE.findall(text):
                    if other != topic:
                        edges.setdefault((topic, other), []).append(os.path.relpath(path, root))
    return edges


def find_cycle(edges):
    """One cycle as a list of topics [a, b, ..., a], or None."""
    successors = {}
    for a, b in edges:
        successors.setdefault(a, set()).add(b)
    state = {}  # topic -> "open" (on the current path) or "done"
    path = []

    def visit(topic):
        state[topic] = "open"
        path.append(topic)
        for following in sorted(successors.get(topic, ())):
            if state.get(following) == "open":
                return path[path.index(following):] + [following]
            if following not in state:
                found = visit(following)
                if found:
                    return found
        path.pop()
        state[topic] = "done"
        return None

    for topic in sorted(successors):
        if topic not in state:
            found = visit(topic)
            if found:
                return found
    return None


def problems(edges):
    out = []
    cycle = find_cycle(edges)
    if cycle:
        files = []
        for a, b in zip(cycle, cycle[1:]):
            files += ["%s (-> %s)" % (f, b) for f in edges[(a, b)][:3]]
        out.append("include cycle between topics: %s; made by %s. Fix: move the shared "
                   "idea into the lower topic, or the file into the topic that uses it"
                   % (" -> ".join(cycle), ", ".join(files)))
    for (a, b), files in sorted(edges.items()):
        if a == "formats":
            out.append("formats/ includes the %s topic (%s): file formats know nothing of "
                       "algorithms; move what it needs into formats/" % (b, ", ".join(files[:3])))
    return out


def check(root):
    edges = include_edges(root)
    if not edges:
        print("include_graph: no library sources under %s" % root, file=sys.stderr)
        return 1
    for (a, b), files in sorted(edges.items()):
        print("%-8s -> %-8s (%d file%s)" % (a, b, len(files), "" if len(files) == 1 else "s"))
    found = problems(edges)
    for p in found:
        print("include_graph: error: " + p, file=sys.stderr)
    return 1 if found else 0


def self_test():
    """A made-up tree with a three-topic cycle and a formats include must fail; without them pass."""
    def write(root, path, text):
        full = os.path.join(root, path)
        os.makedirs(os.path.dirname(full), exist_ok=True)
        with open(full, "w") as f:
            f.write(text)

    with tempfile.TemporaryDirectory() as root:
        write(root, "libflowvid/src/cloth/a.cpp", '#include "flowvid/optim/b.hpp"\n')
        write(root, "libflowvid/include/flowvid/optim/b.hpp", '#include "flowvid/video/c.hpp"\n')
        write(root, "libflowvid/src/video/c.cpp", '#include "flowvid/video/c.hpp"\n')
        write(root, "formats/src/f.cpp", '#include "flowvid/formats/f.hpp"\n')
        assert check(root) == 0, "an acyclic tree must pass"
        write(root, "libflowvid/include/flowvid/video/c.hpp", '  #  include "flowvid/cloth/a.hpp"\n')
        cycle = find_cycle(include_edges(root))
        assert cycle == ["cloth", "optim", "video", "cloth"], cycle
        assert check(root) == 1, "a cycle must fail"
        write(root, "libflowvid/include/flowvid/video/c.hpp", "\n")
        write(root, "formats/src/g.cpp", '#include "flowvid/optim/b.hpp"\n')
        assert len(problems(include_edges(root))) == 1
        assert check(root) == 1, "formats including an algorithm topic must fail"
    print("include_graph: self-test passed")
    return 0


def main(argv):
    if argv[1:] == ["--self-test"]:
        return self_test()
    root = argv[1] if len(argv) > 1 else os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    return check(root)


if __name__ == "__main__":
    sys.exit(main(sys.argv))
