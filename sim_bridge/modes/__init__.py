"""ArduSub's flight modes beyond MANUAL on the built-in vehicle, one file each as ArduSub keeps its mode_*.cpp.

- auto: AUTO mode: the stored mission's waypoints, at a depth or above the bottom
- gates: the mode numbers and the gates a mode change passes
- guided: GUIDED mode's position controller
- stabilize: the assisted modes' attitude, depth and position holds
- surface: SURFACE mode and the surface detector
- terrain: the down-looking rangefinder and SURFTRAK's range hold
- wpnav: AC_WPNav's straight leg from waypoint to waypoint, and the stopping point
"""
