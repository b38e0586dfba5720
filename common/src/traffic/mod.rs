//! Surrounding traffic: IDM car following, MOBIL lane changes, scripted manoeuvres, pedestrians, parked vehicles.
