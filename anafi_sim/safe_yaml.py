"""The one loader for YAML that comes from outside the package (pure Python: pyyaml's safe loader, bounded).

Fleet files, scenario files, model files named by a parameter, commands on a topic: anyone may have written them.
``load_yaml`` / ``load_yaml_text`` parse with ``yaml.SafeLoader`` (no Python objects) and refuse, with a
``ValueError`` of one line, a document

- larger than ``MAX_BYTES``;
- whose expanded size (every alias counted as a copy of what it names: what a program walking the result would
  see) exceeds ``MAX_NODES`` nodes, so an alias bomb is refused after composing its few hundred nodes, before
  anything is built from it;
- that is not valid YAML: the error names the line and column and the parser's problem, never the file's text.
"""
import yaml

#: bytes, the largest document read
MAX_BYTES = 1 << 20
#: nodes of the expanded document (aliases counted as copies)
MAX_NODES = 200000


def _expanded_size(node, limit):
    """Nodes of ``node`` with every alias expanded (shared nodes counted each time), stopping past ``limit``."""
    sizes = {}

    def size(n, depth):
        key = id(n)
        if key in sizes:
            if sizes[key] is None:        # a cycle (a recursive alias): infinite when expanded
                return limit + 1
            return sizes[key]
        if depth > 500:
            return limit + 1
        sizes[key] = None
        total = 1
        if isinstance(n, yaml.SequenceNode):
            children = n.value
        elif isinstance(n, yaml.MappingNode):
            children = [x for pair in n.value for x in pair]
        else:
            children = ()
        for child in children:
            total += size(child, depth + 1)
            if total > limit:
                break
        sizes[key] = total
        return total

    return size(node, 0)


def load_yaml_text(text, what='YAML', max_bytes=MAX_BYTES, max_nodes=MAX_NODES):
    """The data of the YAML document ``text`` (str or bytes); ValueError (one line, naming ``what``) when it is
    too large, expands past ``max_nodes`` nodes or is not valid YAML."""
    if isinstance(text, bytes):
        size = len(text)
    else:
        text = str(text)
        size = len(text.encode('utf-8', 'replace'))
    if size > max_bytes:
        raise ValueError('%s: larger than %d bytes' % (what, max_bytes))
    loader = yaml.SafeLoader(text)
    try:
        node = loader.get_single_node()
        if node is None:
            return None
        if _expanded_size(node, max_nodes) > max_nodes:
            raise ValueError('%s: refused: more than %d nodes once its aliases are expanded' % (what, max_nodes))
        return loader.construct_document(node)
    except yaml.MarkedYAMLError as error:
        mark = error.problem_mark or error.context_mark
        where = ' at line %d, column %d' % (mark.line + 1, mark.column + 1) if mark is not None else ''
        problem = (error.problem or error.context or 'parse error')[:120]
        raise ValueError('%s: not valid YAML%s: %s' % (what, where, problem))
    except yaml.YAMLError as error:
        raise ValueError('%s: not valid YAML: %s' % (what, type(error).__name__))
    except RecursionError:
        raise ValueError('%s: refused: nested too deeply' % what)
    finally:
        loader.dispose()


def load_yaml(path, what=None, max_bytes=MAX_BYTES, max_nodes=MAX_NODES):
    """``load_yaml_text`` of the file ``path`` (read at most ``max_bytes`` + 1 bytes); ValueError naming the file
    (or ``what``) when it cannot be read, is too large or refused. Errors never quote the file's text."""
    what = what or path
    try:
        with open(path, 'rb') as f:
            data = f.read(max_bytes + 1)
    except OSError as error:
        raise ValueError('%s: cannot be read: %s' % (what, error.strerror or type(error).__name__))
    try:
        text = data.decode('utf-8')
    except UnicodeDecodeError:
        raise ValueError('%s: not UTF-8 text' % what)
    return load_yaml_text(text, what, max_bytes, max_nodes)
