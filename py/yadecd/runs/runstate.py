"""Run state independent of class layouts: what a resume needs, in a versioned ``.npz``.

YADE's own checkpoint (``O.save``) is a binary archive of every serialized attribute of every
class; adding one attribute to a plugin class makes older archives unloadable. This module saves
the *physical* state instead, as plain arrays that any later plugin version can read:

=====================  ==========  =============================================================
array                  shape       meaning (SI)
=====================  ==========  =============================================================
``format``             ()          ``'yadecd-runstate'``
``format_version``     ()          2 (readers refuse newer versions with a clear message; version 1,
                                   before clumps, has no ``clump_id`` and still loads)
``plugin_digest``      ()          SHA-256 of the plugin library that wrote the file
``yade_version``       ()          YADE's version string
``time``, ``iter``     ()          simulated time [s] and step count of the run (offsets included)
``dt``                 ()          time step [s]
``body_id``            (n,)        body ids, ascending; ``body_kind``: 0 wall, 1 sphere, 2 clump
``clump_id``           (n,)        the clump a sphere belongs to (-1: none; a clump's own row: -1)
``pos``, ``vel``       (n, 3)      centre [m], velocity [m/s]
``ori``                (n, 4)      orientation quaternion (w, x, y, z)
``angVel``             (n, 3)      angular velocity [rad/s]
``radius``             (n,)        sphere radius [m] (0 for walls and clumps)
``mass``               (n,)        mass [kg] (a clump's: its members' sum, as YADE computed it)
``fixed``              (n,)        True for bodies that do not move
``wall_axis``          (n,)        wall normal axis (0, 1, 2; -1 for spheres); ``wall_sense``
``c_id1``, ``c_id2``   (m,)        bodies of each CD contact, in the order of ``O.interactions``
``c_impulse``          (m, 3)      contact impulse on body 2 over the last step [N·s] (warm start)
``c_status``           (m,)        0 open, 1 sticking, 2 sliding
``c_allowance``        (m,)        overlap the contact may keep [m] (NaN: not yet set)
``c_approach``         (m, 3)      relative velocity at landing [m/s] (restitution)
``x_<name>``           any         arrays of the caller (e.g. a pile's birth times)
=====================  ==========  =============================================================

:func:`restore_bodies` and :func:`restore_contacts` put a saved state back into a scene whose
bodies were created again (same ids, kinds, radii and clump memberships) by the code that builds
a new run. A clump's row holds its own state (centre of mass, principal orientation); its members'
rows hold theirs, so a restored clump and its members agree exactly as saved. The
continuation is the same physical state: positions, velocities and warm-start impulses are
exact; it is not bit-identical to an uninterrupted run (the collider and the contact order start
afresh), which the fast path (``O.load`` of YADE's archive, when the plugin is the same) is.
"""
import hashlib
import os

import numpy as np

from yade import O, Quaternion, Vector3
from yade.wrapper import Clump, Sphere, Wall, CDPhys

FORMAT = 'yadecd-runstate'
FORMAT_VERSION = 2
PLUGIN = 'libpkg_contactdynamics.so'


class RunStateError(RuntimeError):
    """A run-state file that cannot be read, or does not fit the scene it is restored into."""


_digest_cache = {}


def plugin_path():
    """Path of the plugin library this process has loaded (from /proc/self/maps; else the one in
    YADE's plugin directory)."""
    try:
        with open('/proc/self/maps') as f:
            for line in f:
                if line.rstrip().endswith(PLUGIN):
                    return line.split(None, 5)[-1].strip()
    except OSError:
        pass
    import yade.config
    return os.path.join(yade.config.libDir, 'plugins', PLUGIN)


def plugin_digest():
    """SHA-256 of the loaded plugin library: two runs with the same digest have the same class
    layouts, so YADE's own archive of one loads in the other."""
    path = plugin_path()
    if path not in _digest_cache:
        h = hashlib.sha256()
        with open(path, 'rb') as f:
            for block in iter(lambda: f.read(1 << 20), b''):
                h.update(block)
        _digest_cache[path] = h.hexdigest()
    return _digest_cache[path]


def yade_version():
    """YADE's version string, or 'unknown' outside YADE."""
    try:
        import yade.config
        return str(yade.config.version)
    except (ImportError, AttributeError):
        return 'unknown'


def capture(path, time, iteration, extra=None):
    """Write the scene's state to ``path`` (an ``.npz``, written under a temporary name and
    renamed). ``time`` and ``iteration`` are the run's clock (which may differ from O.time and
    O.iter after a rebuild); ``extra`` maps names to arrays stored as ``x_<name>``."""
    bodies = [b for b in O.bodies if b is not None]
    n = len(bodies)
    kind = np.array([body_kind(b) for b in bodies], dtype=np.int8)
    arrays = dict(
        format=np.array(FORMAT), format_version=np.array(FORMAT_VERSION), plugin_digest=np.array(plugin_digest()),
        yade_version=np.array(yade_version()), time=np.array(float(time)), iter=np.array(int(iteration)),
        dt=np.array(float(O.dt)),
        body_id=np.array([b.id for b in bodies], dtype=np.int64), body_kind=kind,
        pos=np.array([tuple(b.state.pos) for b in bodies], dtype=float).reshape(n, 3),
        vel=np.array([tuple(b.state.vel) for b in bodies], dtype=float).reshape(n, 3),
        ori=np.array([(q[3], q[0], q[1], q[2]) for q in (b.state.ori for b in bodies)], dtype=float).reshape(n, 4),
        angVel=np.array([tuple(b.state.angVel) for b in bodies], dtype=float).reshape(n, 3),
        radius=np.array([b.shape.radius if isinstance(b.shape, Sphere) else 0.0 for b in bodies]),
        clump_id=np.array([b.clumpId if b.isClumpMember else -1 for b in bodies], dtype=np.int64),
        mass=np.array([b.state.mass for b in bodies], dtype=float),
        fixed=np.array([not b.dynamic for b in bodies], dtype=bool),
        wall_axis=np.array([b.shape.axis if isinstance(b.shape, Wall) else -1 for b in bodies], dtype=np.int8),
        wall_sense=np.array([b.shape.sense if isinstance(b.shape, Wall) else 0 for b in bodies], dtype=np.int8),
    )
    ids1, ids2, imp, status, allow, approach = [], [], [], [], [], []
    for i in O.interactions:
        if not i.isReal or not isinstance(i.phys, CDPhys):
            continue
        ids1.append(i.id1)
        ids2.append(i.id2)
        imp.append(tuple(i.phys.impulse))
        status.append(i.phys.status)
        allow.append(i.phys.overlapAllowance)
        approach.append(tuple(i.phys.approachVelocity))
    m = len(ids1)
    arrays.update(c_id1=np.array(ids1, dtype=np.int64), c_id2=np.array(ids2, dtype=np.int64),
                  c_impulse=np.array(imp, dtype=float).reshape(m, 3), c_status=np.array(status, dtype=np.int8),
                  c_allowance=np.array(allow, dtype=float), c_approach=np.array(approach, dtype=float).reshape(m, 3))
    for name, value in (extra or {}).items():
        arrays['x_' + name] = np.asarray(value)
    tmp = path + '.tmp'
    with open(tmp, 'wb') as f:
        np.savez_compressed(f, **arrays)
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, path)


KINDS = {Wall: 0, Sphere: 1, Clump: 2}


def body_kind(b):
    """The run-state code of a body's shape (0 wall, 1 sphere, 2 clump).

    :raises RunStateError: for any other shape, naming the body."""
    for cls, code in KINDS.items():
        if isinstance(b.shape, cls):
            return code
    raise RunStateError('body %d is a %s: run states hold walls, spheres and clumps of spheres only'
                        % (b.id, type(b.shape).__name__))


def read(path):
    """The arrays of a run-state file as a dict, after checking its format and version.

    :raises RunStateError: not a run-state file, unreadable, or written by a newer format."""
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError, EOFError) as e:
        raise RunStateError('run state %s is unreadable: %s' % (path, e)) from e
    if str(data.get('format', '')) != FORMAT:
        raise RunStateError('%s is not a %s file' % (path, FORMAT))
    version = int(data.get('format_version', 0))
    if version > FORMAT_VERSION:
        raise RunStateError('%s has run-state format %d; this plugin reads up to %d: update the plugin'
                            % (path, version, FORMAT_VERSION))
    if version < 2:     # format 1 (before clumps): no sphere belongs to a clump
        data['clump_id'] = np.full(len(data['body_id']), -1, dtype=np.int64)
    return data


def extra(data, name):
    """The caller's array ``name`` of a run state (KeyError names it when absent)."""
    key = 'x_' + name
    if key not in data:
        raise KeyError('run state has no %r array' % name)
    return data[key]


def restore_bodies(data):
    """Set position, orientation, velocity and angular velocity of every body of the scene from a
    run state. The scene must hold the same bodies (ids, kinds, radii, clumps and their masses, fixed
    flags; :func:`check_body`): anything else raises :class:`RunStateError` naming the first difference, before any body is changed."""
    ids = data['body_id']
    present = [b.id for b in O.bodies if b is not None]
    if present != ids.tolist():
        raise RunStateError('the rebuilt scene has bodies %s…, the run state %s… (%d vs %d bodies)'
                            % (present[:5], ids[:5].tolist(), len(present), len(ids)))
    for k, bid in enumerate(ids.tolist()):
        check_body(O.bodies[bid], data, k)
    row = {bid: k for k, bid in enumerate(ids.tolist())}
    for k, bid in enumerate(ids.tolist()):
        b = O.bodies[bid]
        s = b.state
        s.pos = Vector3(*data['pos'][k])
        w, x, y, z = data['ori'][k]
        if not b.isClump or _frame_fits(b, Quaternion(w, x, y, z), data, row):
            s.ori = Quaternion(w, x, y, z)
        s.vel = Vector3(*data['vel'][k])
        s.angVel = Vector3(*data['angVel'][k])
        s.refPos = s.pos


def _frame_fits(clump, ori, data, row):
    """Whether the saved orientation ``ori`` of ``clump`` places its members, at their positions
    relative to the clump's frame in the scene, where the run state has them (to 1e-9 of their
    radius). A rebuilt clump's frame is the principal frame YADE computes anew from the members;
    where the inertia has equal moments (an axisymmetric or isotropic clump) that frame may differ
    from the saved one by a symmetry of the inertia, and the saved orientation would then move the
    members. The scene's frame is kept in that case: the members, the inertia in the global frame
    and the velocities are the saved ones, which is the physical state."""
    for mid, (rel, _) in clump.shape.members.items():
        k = row[mid]
        placed = Vector3(*data['pos'][row[clump.id]]) + ori * rel
        if (placed - Vector3(*data['pos'][k])).norm() > 1e-9 * max(float(data['radius'][k]), 1e-300):
            return False
    return True


def check_body(b, data, k):
    """Raise :class:`RunStateError` naming body ``b`` if it differs from row ``k`` of a run state in
    kind, radius, clump membership or fixity (what the rebuilt scene must share with the saved one)."""
    names = {0: 'wall', 1: 'sphere', 2: 'clump'}
    kind, saved = body_kind(b), int(data['body_kind'][k])
    if kind != saved:
        raise RunStateError('body %d is a %s in the scene, a %s in the run state' % (b.id, names[kind], names.get(saved, saved)))
    if kind == 1 and b.shape.radius != data['radius'][k]:
        raise RunStateError('body %d has radius %r in the scene, %r in the run state' % (b.id, b.shape.radius, data['radius'][k]))
    clump = b.clumpId if b.isClumpMember else -1
    if clump != int(data['clump_id'][k]):
        raise RunStateError('body %d belongs to clump %d in the scene, to %d in the run state (-1: none)'
                            % (b.id, clump, int(data['clump_id'][k])))
    if kind == 2 and abs(b.state.mass - data['mass'][k]) > 1e-12 * abs(data['mass'][k]):
        raise RunStateError('clump %d has mass %r in the scene, %r in the run state' % (b.id, b.state.mass, data['mass'][k]))
    if (not b.dynamic) != bool(data['fixed'][k]):
        raise RunStateError('body %d is %s in the scene but not in the run state' % (b.id, 'fixed' if not b.dynamic else 'free'))


def restore_contacts(data):
    """Create the saved CD contacts (by YADE's own dispatchers, as the collider would) and give
    them their warm-start impulse, status, overlap allowance and approach velocity. Returns the
    number of contacts restored; a pair that cannot be created (bodies now far apart) is skipped
    and counted in the second returned value."""
    from yade import utils
    restored = skipped = 0
    dt = float(O.dt)
    for k in range(len(data['c_id1'])):
        id1, id2 = int(data['c_id1'][k]), int(data['c_id2'][k])
        try:
            i = utils.createInteraction(id1, id2)
        except RuntimeError:
            skipped += 1
            continue
        ph = i.phys
        if not isinstance(ph, CDPhys):
            raise RunStateError('contact %d-%d was restored with %s, not CDPhys: the scene has no CD engines'
                                % (id1, id2, type(ph).__name__))
        ph.impulse = Vector3(*data['c_impulse'][k])
        ph.status = int(data['c_status'][k])
        ph.overlapAllowance = float(data['c_allowance'][k])
        ph.approachVelocity = Vector3(*data['c_approach'][k])
        # forces as the solver leaves them (impulse/dt split along the normal), for analyses
        n = i.geom.normal
        f = ph.impulse / dt
        ph.normalForce = n * n.dot(f)
        ph.shearForce = f - ph.normalForce
        restored += 1
    return restored, skipped
