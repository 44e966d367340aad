"""Pictures: offscreen videos (:mod:`flapsim.render.video`) and the one interactive viewer
loop (:mod:`flapsim.render.viewer`) shared by the dove and the swimmer."""
