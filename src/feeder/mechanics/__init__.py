"""Analytic mechanics: how a part leaves passive fences, from its outline alone.

A flat part carried by the belt into a passive fence turns until an edge of its convex hull lies
flush against the fence, then slides along it (quasi-static pushing: Mason 1986; Peshkin &
Sanderson 1988; Goldberg 1993, "Orienting polygonal parts without sensors"; for fences over a
belt, Wiegley, Goldberg, Peshkin & Brokowski 1996). This package computes that response from the
outline polygon (the part file's own frame, metres, as :func:`feeder.parts.geometry.read_outline`
and :class:`~feeder.parts.geometry.PartGeometry` give it) and the scene's fence geometry, and turns
a fence configuration into an analytic 360-bin PMF and a fixed-size feature block. Everything is a
pure function of its arguments; the only file read is the study config when no ``scene`` is given
(:func:`feeder.mechanics.fence.default_scene`).

One module per concept, each building on the ones before it:

* :mod:`~feeder.mechanics.hull`: the convex hull about the area centroid, its radius function;
* :mod:`~feeder.mechanics.pushfunction`: stable edges and their basins against a fence (Goldberg's
  push function with fence friction), and where a rolling part leaves;
* :mod:`~feeder.mechanics.fence`: a fence face's orientation and friction cone, and the fences of
  a configuration as the part meets them (built by :mod:`feeder.lane.geometry`);
* :mod:`~feeder.mechanics.exitturn`: the turn of a part leaving a fence tip;
* :mod:`~feeder.mechanics.distribution`: evenly spaced drops pushed through a configuration;
* :mod:`~feeder.mechanics.pmf`: the analytic PMF of a configuration;
* :mod:`~feeder.mechanics.features`: the push feature block of a part in a configuration.

Conventions (checked against the simulator; file and line references as of this module)
    * Yaw: ``feeder.sim.body.World.add_part`` sets the body yaw to ``yaw + alpha`` with the body
      in the principal frame (``part_model`` rotates the pieces by ``−alpha``), so a recorded yaw
      ``y`` (``feeder.sim.drops``: ``degrees(yaw_rad − alpha)``) turns the part file's outline by
      ``y`` about its area centroid: a part-frame direction ``φ`` points along ``φ + y`` in the
      world.
    * World: parts travel along ``+y``, ``+x`` is the right-hand side (``feeder.sim.scene``).
      Location 1 (downstream) is on the right (``side = +1``), Location 2 (upstream) on the left
      (``side = −1``); ``scene.mirror`` swaps them (``feeder.sim.scene.location_side``). A part
      meets Location 2 first (``scene_fences`` lists it first).
    * A straight fence at ``θ`` runs from the wall downstream and inward along
      ``(−side·sin θ, cos θ)`` (``straight_polyline``); its face seen by the part has the normal
      ``(−side·cos θ, −sin θ)``, so a flush edge's outward normal points along
      ``ψ = atan2(sin θ, side·cos θ)``: ``θ`` on the right, ``180° − θ`` on the left
      (``tests/test_sim_physics.py``: a rectangle flush on the right fence at 45° has its long
      axis along 135°). The resting yaw of an edge of part-frame normal ``φ_e`` is ``ψ − φ_e``.
    * A curved fence at ``θ`` is an arc whose local fence angle (between its tangent and the
      travel direction) runs from ``θ + span`` at the slot to ``θ`` at the tip
      (``curved_polyline``: the tangent at polar angle ``φ`` is ``(sin φ, −cos φ)``, i.e. angle
      ``φ + 180°``). Its face is the chain of box chords (``arc_boxes``), so the part leaves it
      along the **last chord**, at ``θ + span / (2 · segments)`` (2.8° more than the exit tangent
      with the default 16 boxes): that is the effective straight fence used for the resting
      yaw (an approximation: a part wider than a chord rests on chord corners).
    * Labels: ``labels.frame: principal`` measures ``yaw + frame_deg``
      (``feeder.labels.dataset.label_yaws``), ``frame_deg`` from
      :func:`feeder.parts.features.frame_deg`; :func:`analytic_pmf` takes ``frame_deg`` (0: the
      part file's frame) and bins like :func:`feeder.labels.metrics.histogram`.
"""
