"""Animated fitting: a garment draped at rest, then on the body moving through a walk or a BVH motion.

* :mod:`.motion`: the clip (the built-in walk, a BVH file in the rig's, CMU's or mapped joint names), blended
  in from the A pose, and :class:`~.motion.Poser`, the body and the pins posed frame after frame;
* :mod:`.loop`: :func:`~.loop.animate_garment` (the rest drape, then :func:`~.loop.run_animation`), the cloth
  simulated on the moving body (:class:`vfit_engine.collide.moving_body.MovingBodyCollider`);
* :mod:`.outputs`: the report (every frame's figures, the quality bars, the time per frame), the animated GLB,
  the preview GIF.
"""
from vfit_engine.animate.loop import AnimateSettings, AnimationResult, animate_garment, run_animation  # noqa: F401
from vfit_engine.animate.motion import Clip, Poser, load_clip  # noqa: F401
